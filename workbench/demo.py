"""``make demo``: the main job on the built-in defaults.

It solves the built-in CD cell over a few wavelengths and prints each one's diffraction
orders, then renders the built-in Cornell-box scene with the CD (draft preset; its
efficiency table is built through the table cache on first use), then generates the
default synthetic dataset (seeded, so the same bytes every time: raw photos, exposure
brackets and a calibration set, with the truth beside them). Later stages add the
calibration and the report.
"""

from __future__ import annotations

import time

import rcwa
from workbench.report_text import solve_table

DEMO_WAVELENGTHS_NM = (400.0, 500.0, 600.0, 700.0)
DEMO_THETA_DEG = 30.0
DEMO_ORDERS = 61
DEMO_RENDER = "out/demo/cornell_cd.exr"
DEMO_DATASET = "out/demo/dataset"
DEMO_SEED = 0


def run_demo() -> int:
    structure = rcwa.load_structure("cd")
    print(f"Built-in structure 'cd' ({structure.source}), unpolarized light at {DEMO_THETA_DEG:g} deg, "
          f"{DEMO_ORDERS} harmonics, Li's inverse rule.\n")
    for wavelength in DEMO_WAVELENGTHS_NM:
        start = time.perf_counter()
        result = rcwa.solve(structure, wavelength, DEMO_THETA_DEG, 0.0, DEMO_ORDERS, "unpolarized")
        print(solve_table(result))
        print(f"({(time.perf_counter() - start) * 1e3:.1f} ms)\n")
    from renderer.render import render, summary

    print("Rendering the built-in scene cornell_cd (draft preset) ...")
    info = render("cornell_cd", DEMO_RENDER, preset="draft", force=True)  # out/demo is the demo's own folder
    print(f"\n{summary(info)}")
    from datasets_synthetic.synth import synth

    print(f"\nGenerating the default synthetic dataset (seed {DEMO_SEED}, draft preset) ...")
    start = time.perf_counter()
    synth("cornell_cd", DEMO_DATASET, seed=DEMO_SEED, preset="draft", force=True)
    print(f"Dataset: {DEMO_DATASET}/ (photos/, brackets/, calibration/, truth.json, run.json) "
          f"in {time.perf_counter() - start:.1f} s.")
    return 0
