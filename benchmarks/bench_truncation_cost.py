"""Benchmark: the planner's estimate of a table's truncation-error sample against a build's
own record of it (issue 29, item 3).

Per scene (cornell_cd: the CD, 1D; grating2d_gold: the gold block, 2D) at a preset
(draft unless given): the planner's estimate (renderer.table_cost: the sample run at the
middle wavelength, scaled to the table's wavelengths) of the sample's seconds, against
what the whole table records when built in a fresh process (as a render builds it: its
once-per-process costs paid there too) in an empty cache (rcwa.table.truncation.summary);
and the sample's share of the table's solves, estimated (the sample over the planner's
estimate of the solves) and recorded (over the chunks' seconds), with the solves'
estimate against the chunks' record, which explains most of the shares' difference.
Run: ``python -m benchmarks.bench_truncation_cost [PRESET]``.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import tempfile

from rcwa.table import build_table, read_table_metadata, truncation_summary
from renderer.scene import load_scene
from renderer.tables import table_plan
from renderer.trace.planner import plan_scene
from workbench.core.cache import ENVIRONMENT_VARIABLE

SCENES = ("cornell_cd", "grating2d_gold")


def _at_preset(spec, preset: str):
    table = {"preset": preset}
    return dataclasses.replace(spec, cds=tuple(dataclasses.replace(c, table=table) for c in spec.cds),
                               gratings=tuple(dataclasses.replace(g, table=table) for g in spec.gratings))


def _elements(spec) -> list:
    return [(f"cd[{i}]", cd) for i, cd in enumerate(spec.cds)] + [(f"grating[{i}]", g) for i, g in enumerate(spec.gratings)]


def build(scene: str, where: str, preset: str) -> None:
    """Build the whole table of ``scene``'s element ``where`` (run in a fresh process by main)."""
    element = dict(_elements(_at_preset(load_scene(scene), preset)))[where]
    table = table_plan(element, where, None)
    build_table(table.structure, table.settings, table.path, progress=False)


def main(preset: str = "draft") -> None:
    print(f"truncation-error sample, estimated by the planner against a whole {preset} table's record")
    print(f"{'element':24s} {'est. s':>7s} {'built s':>7s} {'ratio':>6s} {'est. share':>10s} {'built share':>11s} "
          f"{'solves est./built':>17s}")
    for name in SCENES:
        spec = _at_preset(load_scene(name), preset)
        os.environ[ENVIRONMENT_VARIABLE] = tempfile.mkdtemp(prefix="bench-truncation-")
        plan = {e.key: e for e in plan_scene(spec, measure_cost=True).elements}
        for where, element in _elements(spec):
            e = plan[where]
            estimated = e.truncation["seconds_whole"]
            solves = e.seconds_whole - estimated
            subprocess.run([sys.executable, "-c", "import sys; from benchmarks.bench_truncation_cost import build; "
                            "build(*sys.argv[1:])", name, where, preset], check=True)
            meta = read_table_metadata(table_plan(element, where, None).path)
            built = truncation_summary(meta)
            assert built is not None
            chunks = sum(meta["chunk_seconds"].values())
            print(f"{name + ' ' + where:24s} {estimated:7.2f} {built['sample_seconds']:7.2f} "
                  f"{estimated / built['sample_seconds']:6.2f} {estimated / max(solves, 1e-12):10.1%} "
                  f"{built['sample_share']:11.1%} {solves / chunks:17.2f}")


if __name__ == "__main__":
    main(*sys.argv[1:2])
