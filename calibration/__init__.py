"""Camera calibration from photographs (the calibration layer; imports rcwa, renderer and
workbench.core, never the command line, never datasets_synthetic).

One subpackage per step, each with its command's entry point in ``calibrate``:

- ``raw``: photos in: ``decode`` (raw and developed files to linear camera RGB), ``layout``
  (each sensor layout LibRaw reads), ``checks`` (damaged or unsupported raws refused).
- ``board``: calibration boards in board views: ``corners`` and ``charuco`` find them,
  ``corner_refinement`` (point symmetry), ``border`` (the grid is the whole board),
  ``board_file`` (board.json), ``images`` (pixel arrays as the finders want them).
- ``intrinsics``: ``calibrate`` (``workbench calibrate intrinsics``), ``fit`` (Zhang's
  model from found corners), ``lens_models`` and ``lens_choice`` (the model and its terms by
  held-out views), ``projection_uncertainty``, ``vignetting`` and ``vignetting_stage``.
- ``response``: ``calibrate``, ``bracket`` (reading a bracket), ``methods`` (Debevec,
  Robertson, parametric), ``record`` (response.json).
- ``pose``: ``calibrate`` (``workbench calibrate pose``), ``inputs``, ``photo``,
  ``scene_model`` (the scene's edges), ``edges`` (the photo's), ``edge_fit``, ``stages`` (one
  photo through every stage), ``render_check``, ``fringe_rotation`` (the CD-fringe check),
  ``uncertainty``, ``outputs``, ``scene_file`` (the scene file with the fitted camera),
  ``study`` (``workbench study calibrate``).
- ``dataset``: every step on a dataset folder (``workbench calibrate DATASET``);
  ``calibration_file``: calibration.json, its one writer and its one reader.
"""
