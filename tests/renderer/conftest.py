"""Renderer tests share one Mitsuba variant per process (renderer.variant sets it once)."""

import pytest


@pytest.fixture(scope="session")
def mitsuba_variant():
    from renderer.variant import set_variant

    return set_variant()


@pytest.fixture(scope="session")
def cd_table(tmp_path_factory):
    import rcwa
    from rcwa.table import build_table, open_table, settings_for

    s = rcwa.load_structure("cd")
    st = settings_for(s, "draft", wavelengths="380:780:9", theta_step=10.0, phi_step=15.0, orders=21, keep=7, pol="all")
    path = tmp_path_factory.mktemp("tables") / "cd.zarr"
    build_table(s, st, path, progress=False)
    return open_table(path)
