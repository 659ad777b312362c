"""Reports: a photograph and a render of the same view compared, the CD's colour fringes measured,
and the scene parameters the photos constrain.

- ``report``: ``workbench report``, the whole report of one photo.
- ``table_error``: the tables' own truncation errors. The fitted camera comes from
  calibration.calibration_file (calibration.json's one writer and reader).
- ``compare``: photo and render in one space (``images``, ``merged_photo``, ``exposure_merge``),
  error maps (``metrics``), per-region tests (``regions``, ``photo_noise``).
- ``fringes``: what is measured on the CD: ``rim``, ``polar`` (the disk unwrapped), ``band_edges``,
  ``hue``, ``cd_shadow`` (where the CD's shadow makes an edge), ``prediction_band`` (the
  prediction's uncertainty band). The prediction itself is renderer.trace.prediction.
- ``scene_fit``: the inverse problem: ``model`` (band edges and rim for scene parameters),
  ``fit``, ``bias`` (the forward model's own offsets), ``structure_tables``, ``verdict``,
  ``apply`` (a scene with fitted values), ``outputs``, ``job`` (``workbench fit``), ``study``.
- ``page``: the HTML, apart from what measures: ``html``, ``tiles``, ``summary``,
  ``verdict_block``, ``fringe_overlay``, ``fringe_plot``, ``lens_maps``, ``study_figures``,
  ``run_index`` (a verify run's index page).
"""
