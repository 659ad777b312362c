"""Benchmark: what the planner saves (issue 16; ``make bench``).

Per scene (cornell_cd, cornell_cd_view2, grating2d_gold), in one run:
* measured at the draft preset: the wall time of the whole table and of the table
  planned for the scene's camera (each built in an empty cache), and their ratio;
* estimated at the paper preset by the planner's cost model (a timed sample of solves
  with the table's orders and with the fill's): the planned share of the whole time;
* the share of (wavelength, theta, phi) nodes the camera's rays read, which explains
  the fraction: a CD's radial grooves turn every azimuth of the grating frame into a
  needed one, while grating2d_gold's one groove direction, seen from one camera, needs
  thin streaks; the other nodes still cost the fill (the kept orders only).
"""

from __future__ import annotations

import os
import tempfile
import time

from rcwa.table import build_table
from renderer.scene import load_scene
from renderer.tables import table_plan
from renderer.trace.planner import plan_scene, planned_nodes
from workbench.core.cache import ENVIRONMENT_VARIABLE

SCENES = ("cornell_cd", "cornell_cd_view2", "grating2d_gold")


def _elements(spec) -> list:
    return [(f"cd[{i}]", cd) for i, cd in enumerate(spec.cds)] + [(f"grating[{i}]", g) for i, g in enumerate(spec.gratings)]


def _build_seconds(spec, planned: bool) -> float:
    os.environ[ENVIRONMENT_VARIABLE] = tempfile.mkdtemp(prefix="bench-plan-")
    nodes = planned_nodes(spec) if planned else {}
    start = time.perf_counter()
    for where, element in _elements(spec):
        plan = table_plan(element, where, None, nodes.get(where))
        build_table(plan.structure, plan.settings, plan.path, progress=False, nodes=plan.nodes)
    return time.perf_counter() - start


def _paper(spec):
    import dataclasses

    paper = {"preset": "paper"}
    return dataclasses.replace(spec, cds=tuple(dataclasses.replace(c, table=paper) for c in spec.cds),
                               gratings=tuple(dataclasses.replace(g, table=paper) for g in spec.gratings))


def _node_share(plan) -> float:
    return sum(e.directions_needed for e in plan.elements) / max(sum(e.directions_total for e in plan.elements), 1)


def main() -> None:
    print("planned tables against whole tables (issue 16: grating2d_gold should need at most 1/5 at the paper grid)")
    print(f"{'scene':18s} {'nodes read':>10s} {'draft whole s':>13s} {'planned s':>9s} {'ratio':>6s} "
          f"{'paper est. ratio':>16s} {'paper nodes read':>16s} {'saved (paper est.)':>18s}")
    for name in SCENES:
        spec = load_scene(name)
        draft_plan = plan_scene(spec, measure_cost=False)
        whole = _build_seconds(spec, planned=False)
        planned = _build_seconds(spec, planned=True)
        paper_plan = plan_scene(_paper(spec), measure_cost=True)
        est_whole = sum(e.seconds_whole for e in paper_plan.elements)
        est_planned = sum(e.seconds_planned for e in paper_plan.elements)
        nodes, paper_nodes = _node_share(draft_plan), _node_share(paper_plan)
        print(f"{name:18s} {nodes:10.0%} {whole:13.1f} {planned:9.1f} {planned / whole:6.2f} "
              f"{est_planned / est_whole:16.2f} {paper_nodes:16.0%} {est_whole - est_planned:15.0f} s")


if __name__ == "__main__":
    main()
