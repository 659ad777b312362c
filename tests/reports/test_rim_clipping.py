"""The scene fit's rim points leave out a clipped edge (reports.scene_fit.model.photo_rim_points).

The "photo" is cornell_cd's CD seen by the scene's camera, drawn analytically: the grating's
disc (anti-aliased at 8 x 8 sub-pixels) over a mid-grey floor, blurred by a Gaussian of
1 px (a lens and demosaicing's spread). On the left half of the image the disc is 3 x the
sensor's white (the light's band on it), and the photo is clipped at white there. A blurred
step from 3 to 0.5 clipped at 1 keeps its strongest gradient where the clipping ends,
at least 0.84 sigma outside the true edge (the normal quantile of 0.2 = (1 - 0.5) / (3 - 0.5);
the flat top's kink pulls the parabolic peak further: measured 1.37 px median over 27 points),
while the unclipped points sit on the edge (measured median 0.05 px over 25). The fit must
drop the first and keep the second.
"""

from __future__ import annotations

import cv2
import numpy as np

from renderer.scene import load_scene
from renderer.trace.prediction import cd_geometry
from reports.compare.images import Photo
from reports.scene_fit.model import RIM_CLIP_PX, near_clipped, photo_rim_points, rim_residuals

SUPERSAMPLE = 8
BLUR_PX = 1.0
CLIPPED_BIAS_PX = 0.5  # the clipped half's points, without the filter: at least this far out (measured 1.37 px)
KEPT_BAR_PX = 0.2  # the kept points' median distance from the true rim (sub-pixel peak of a clean blurred step)


def _photo():
    spec = load_scene("cornell_cd")
    camera = spec.camera.model
    cd = cd_geometry(spec)
    rim = camera.project(cd.rim_points(count=720))
    size = (camera.height * SUPERSAMPLE, camera.width * SUPERSAMPLE)
    disc = np.zeros(size, np.uint8)
    cv2.fillPoly(disc, [np.round((rim + 0.5) * SUPERSAMPLE - 0.5).astype(np.int32)], 1)
    cover = disc.reshape(camera.height, SUPERSAMPLE, camera.width, SUPERSAMPLE).mean(axis=(1, 3))
    centre_column = float(camera.project(cd.center[None])[0, 0])
    inside = np.where(np.arange(camera.width)[None, :] < centre_column, 3.0, 0.2) * np.ones((camera.height, 1))
    grey = cv2.GaussianBlur((0.5 * (1 - cover) + inside * cover).astype(np.float32), (0, 0), BLUR_PX)
    clipped = grey >= 1.0
    rgb = np.repeat(np.minimum(grey, 1.0)[..., None], 3, axis=2)
    return spec, camera, cd, Photo(rgb, clipped, "drawn", "linear"), centre_column


def test_clipped_rim_points_are_left_out_and_the_rest_sit_on_the_rim() -> None:
    spec, camera, cd, photo, centre_column = _photo()
    kept = photo_rim_points(photo, camera, spec)
    unfiltered = photo_rim_points(Photo(photo.rgb, np.zeros_like(photo.clipped), "drawn", "linear"), camera, spec)
    assert photo.clipped.any() and len(kept) >= 20, (int(photo.clipped.sum()), len(kept))
    assert not near_clipped(photo.clipped, kept, RIM_CLIP_PX).any()
    assert np.all(kept[:, 0] > centre_column - 1), "a point of the clipped (left) half was kept"
    upper = unfiltered[near_clipped(photo.clipped, unfiltered, RIM_CLIP_PX)]
    assert len(upper) >= 10
    assert float(np.median(rim_residuals(camera, cd, upper))) > CLIPPED_BIAS_PX  # why they are dropped
    assert abs(float(np.median(rim_residuals(camera, cd, kept)))) < KEPT_BAR_PX
