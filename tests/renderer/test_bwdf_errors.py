"""Bad input to the BWDF is refused before rendering, with a message naming the file."""

import numpy as np
import pytest

import rcwa
from rcwa.table import build_table, settings_for
from renderer.camera_coverage import SENSITIVITY_THRESHOLD, require_table_covers_camera, visible_range
from workbench.core.errors import UserInputError


def _load(mi, **props):
    from renderer.bwdf import register

    register()
    return mi.load_dict({"type": "bwdf", **props})


def test_missing_table(mitsuba_variant, tmp_path):
    import mitsuba as mi

    with pytest.raises(Exception, match="not an efficiency table") as err:
        _load(mi, filename=str(tmp_path / "nothing.zarr"))
    assert "nothing.zarr" in str(err.value)


def test_corrupted_table(mitsuba_variant, cd_table, tmp_path):
    import shutil

    import mitsuba as mi

    copy = tmp_path / "broken.zarr"
    shutil.copytree(cd_table.path, copy)
    chunk = sorted(p for p in (copy / "R" / "c").rglob("*") if p.is_file())[0]
    data = bytearray(chunk.read_bytes())
    data[-1] ^= 0x55
    chunk.write_bytes(bytes(data))
    with pytest.raises(Exception, match="broken.zarr"):
        _load(mi, filename=str(copy))


def test_2d_table_on_the_radial_mapping(mitsuba_variant, tmp_path):
    import mitsuba as mi

    s = rcwa.load_structure("gold2d")
    st = settings_for(s, "draft", wavelengths="550", theta_step=45.0, phi_step=45.0, orders=3, keep=3, both_sides=True)
    build_table(s, st, tmp_path / "g2.zarr", progress=False)
    with pytest.raises(Exception, match="radial .*1D grating table"):
        _load(mi, filename=str(tmp_path / "g2.zarr"), mapping="radial", center=[0.0, 0.0, 0.0])
    _load(mi, filename=str(tmp_path / "g2.zarr"), mapping="constant")  # fine


@pytest.mark.parametrize("props, message", [
    ({"mapping": "radial"}, "radial .*mapping needs 'center'"),
    ({"mapping": "radial", "center": [0.0, float("nan"), 0.0]}, "'center' must be a point of three finite coordinates"),
    ({"mapping": "radial", "center": "middle"}, "'center' must be a point"),
])
def test_radial_mapping_needs_a_centre(mitsuba_variant, cd_table, props, message):
    """The grooves' centre sets the grating vector at every hit point: no silent default."""
    import mitsuba as mi

    with pytest.raises(Exception, match=message):
        _load(mi, filename=str(cd_table.path), **props)


def test_see_through_table_needs_both_sides(mitsuba_variant, tmp_path):
    import mitsuba as mi

    s = rcwa.load_structure("gold2d")
    st = settings_for(s, "draft", wavelengths="550", theta_step=45.0, phi_step=45.0, orders=3, keep=3)
    build_table(s, st, tmp_path / "one_side.zarr", progress=False)
    with pytest.raises(Exception, match="one_side.zarr.*--both-sides"):
        _load(mi, filename=str(tmp_path / "one_side.zarr"))


def test_bad_settings(mitsuba_variant, cd_table):
    import mitsuba as mi

    with pytest.raises(Exception, match="'mode' must be one of"):
        _load(mi, filename=str(cd_table.path), mode="fast")
    with pytest.raises(Exception, match="'mapping' must be one of"):
        _load(mi, filename=str(cd_table.path), mapping="spiral")
    with pytest.raises(Exception, match="'uniform_share' must be within"):
        _load(mi, filename=str(cd_table.path), uniform_share=1.5)
    for delta in (0.0, -0.1, 0.6):  # Delta above 0.5 would keep every wavelength, at or below 0 none
        with pytest.raises(Exception, match="'delta' must be within"):
            _load(mi, filename=str(cd_table.path), mode="paper", delta=delta)
    with pytest.raises(Exception, match="'grating_angle' must be a finite angle"):
        _load(mi, filename=str(cd_table.path), grating_angle=float("nan"))


def test_table_must_cover_where_the_camera_sees():
    wl = np.arange(360.0, 831.0, 5.0)
    curves = np.stack([np.exp(-0.5 * ((wl - c) / 30.0) ** 2) for c in (460.0, 540.0, 610.0)])
    lo, hi = visible_range(wl, curves)
    assert 360 < lo < 400 and 670 < hi < 720  # 1 % of the peak, about 3 widths out
    require_table_covers_camera("t.zarr", np.array([360.0, 760.0]), wl, curves)
    with pytest.raises(UserInputError, match="t.zarr.*covers 400-700 nm") as err:
        require_table_covers_camera("t.zarr", np.array([400.0, 700.0]), wl, curves)
    assert f"{SENSITIVITY_THRESHOLD:.0%}" in str(err.value)
