"""Camera calibration from photographs (the calibration layer; imports rcwa, renderer and
workbench.core, never the command line).

- Photos in: decode (raw and developed files to linear camera RGB), photo, images.
- Intrinsics from board views: corners and charuco find the board, corner_refinement moves
  each corner to its centre of point symmetry, board_border checks the grid is the whole
  board, board_file reads board.json, intrinsics fits Zhang's model.
- Response curve from a bracket: response (the command), response_bracket (reading),
  response_fit (the methods), response_record (response.json).
- Pose and field of view of a scene photo: pose (the command), pose_inputs (what it reads),
  pose_fit (the edge fit), pose_uncertainty, pose_photo (one photo's stages), pose_outputs
  (what it writes); scene_model (the scene's edges), edges (the photo's), photometric (the
  CD-fringe check), fitted_scene (the scene file with the fitted camera).
- Everything on a dataset folder: dataset (``workbench calibrate DATASET``); pose_study
  (``workbench study calibrate``: accuracy against time, against a synthetic dataset's truth).
"""
