"""``make demo``: the main job on the built-in defaults.

For now (the solver stage of the project) it solves the built-in CD cell over a few
wavelengths and prints each one's diffraction orders; later stages add the table sweep,
the render and the report.
"""

from __future__ import annotations

import time

import rcwa
from workbench.report_text import solve_table

DEMO_WAVELENGTHS_NM = (400.0, 500.0, 600.0, 700.0)
DEMO_THETA_DEG = 30.0
DEMO_ORDERS = 61


def run_demo() -> int:
    structure = rcwa.load_structure("cd")
    print(f"Built-in structure 'cd' ({structure.source}), unpolarized light at {DEMO_THETA_DEG:g} deg, "
          f"{DEMO_ORDERS} harmonics, Li's inverse rule.\n")
    for wavelength in DEMO_WAVELENGTHS_NM:
        start = time.perf_counter()
        result = rcwa.solve(structure, wavelength, DEMO_THETA_DEG, 0.0, DEMO_ORDERS, "unpolarized")
        print(solve_table(result))
        print(f"({(time.perf_counter() - start) * 1e3:.1f} ms)\n")
    return 0
