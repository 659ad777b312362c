"""Rendering with Mitsuba 3: diffractive surfaces in the Cornell-box scene (docs/architecture.md).

Mitsuba's variant is chosen in one place, :mod:`renderer.variant`; no other module calls
``mi.set_variant``. The modules:

Plugins (registered with Mitsuba by ``renderer.plugins.register_plugins``; docs/mitsuba_plugin.md)
    bwdf          the BWDF: a grating's diffraction orders from an RCWA efficiency table,
                  ``type = "bwdf"`` (paper mode, [Lange 2021, Eqs. 2-5], and improved mode)
    dielectric    a dispersive smooth dielectric, ``type = "dispersive_dielectric"``
    emitter       a power-cosine area light, ``type = "cospower_area"``
    delta_lobes   what the two delta-lobe BSDFs share (hero wavelength, zero eval/pdf)
    efficiency    efficiency-table lookups inside Dr.Jit kernels

Scenes and rendering
    scene         scene files (TOML) and their validation; ``scenes/`` holds the built-in ones
    fit_parameters  a scene's ``[fit]`` table: the scene fit's free parameters (applied by
                  reports.scene_fit.apply)
    mitsuba_scene a scene spec to a Mitsuba scene dict (shapes, light, sensor)
    spectra       Mitsuba spectra, the light's emission, the camera's sensitivities
    meshes        the box's quads and the CDs' annuli as PLY files in the cache
    placement     where objects sit in the world (shared with calibration.pose.scene_model)
    tables        which efficiency table serves each CD and grating, built when missing
    camera        the camera model shared with calibration (OpenCV pinhole with distortion)
    response      camera response curves
    camera_coverage  pre-render checks (table coverage of the camera's sensitivities; where the camera looks)
    trace/        the numpy trace, no Mitsuba: ``geometry`` (rays against planes, the box's
                  walls, the light's rectangle, the grating equation), ``planner`` (what a
                  scene needs simulated), ``prediction`` and ``efficiency_weights`` (where the
                  grating equation puts the CD's lit bands, weighted by RCWA efficiencies)
    table_cost    a table's estimated build time on this machine, for the planner
    render        ``workbench render``: passes, resume, EXR, preview, sidecar
    rerender      fast in-place re-renders for calibration (the ``fit`` preset)
    variant       Mitsuba's variant and the libLLVM it needs

Accuracy
    accuracy      error measures on a scene's diffractive elements (shared with benchmarks/)
    render_study  ``workbench study render``: rendering accuracy versus time

``data/`` holds the measured Cornell box (with its provenance).
"""
