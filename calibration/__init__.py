"""Camera calibration from photographs: board corners and intrinsics (the calibration
layer; later issues add pose, exposure and response fitting)."""
