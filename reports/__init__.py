"""Reports: a photograph and a render of the same view compared, the CD's colour fringes measured.

Modules, one job each: ``prediction`` (the grating equation's lit bands, independent of
the renderer), ``polar`` (the CD's disk unwrapped to radius and azimuth through a camera),
``fringes`` (band edges found in an image and compared), ``images`` (decoding photos and
renders to linear camera RGB, region masks, the display transform), ``metrics`` (error
maps), ``page`` (the self-contained HTML page) and ``report`` (the whole report). The
scene fit (``workbench fit``): ``scene_fit_model`` (the forward model: band edges and rim
for scene parameters), ``scene_fit`` (the robust fit and its standard deviations),
``scene_verdict`` (consistent, model, camera or unexplained), ``scene_fit_outputs``,
``scene_fit_job`` (the command's steps) and ``verdict_block`` (the page's first block).
"""
