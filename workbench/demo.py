"""``make demo``: the main job on the built-in defaults, from photos to a report.

1. The default synthetic dataset (``workbench synth cornell_cd --seed 0``, draft: raw
   photos from two viewpoints, an exposure bracket, checkerboard views, and the truth
   beside them) in out/demo/dataset; seeded, so the same bytes every time.
2. ``workbench verify`` on it into out/demo/run: the plan, the CD's table (through the
   table cache), the calibration from the photos alone, the first photo rendered with
   its fitted camera (draft, 256 spp) and the report comparing the two. Only the first
   photo is rendered and reported, to keep the demo within 3 minutes on 2 cores
   (``workbench verify`` does every photo); a second demo finds every stage's inputs
   unchanged and skips them. From an empty table cache and an empty Dr.Jit
   kernel cache the whole job took 162 s of CPU time (user + system, so at most that long
   on 2 quiet cores; 276 s wall on a machine loaded 7-9), the CD's draft table 4 s of it.
3. ``workbench score``: the calibration against the dataset's truth.

It ends with the path of the HTML report.
"""

from __future__ import annotations

import time

from datasets_synthetic.synth import synth
from workbench.score import format_score, score_run
from workbench.verify import VerifySettings, format_summary, verify

DEMO_SCENE = "cornell_cd"
DEMO_DATASET = "out/demo/dataset"
DEMO_RUN = "out/demo/run"
DEMO_SEED = 0
DEMO_PHOTOS = ("view0.dng",)  # the first photo only (see the docstring)


def run_demo() -> int:
    started = time.perf_counter()
    print(f"1/3 the default synthetic dataset: workbench synth {DEMO_SCENE} --seed {DEMO_SEED} (draft) "
          f"-> {DEMO_DATASET}", flush=True)
    synth(DEMO_SCENE, DEMO_DATASET, seed=DEMO_SEED, preset="draft", force=True)  # out/demo is the demo's own folder
    print(f"    done in {time.perf_counter() - started:.0f} s\n", flush=True)
    print(f"2/3 workbench verify {DEMO_DATASET} --scene {DEMO_SCENE} --out {DEMO_RUN} --photo {DEMO_PHOTOS[0]}",
          flush=True)
    record = verify(DEMO_DATASET, DEMO_SCENE, DEMO_RUN, VerifySettings(photos=DEMO_PHOTOS), force=True)
    print(format_summary(record) + "\n")
    print(f"3/3 workbench score {DEMO_RUN} --truth {DEMO_DATASET}/truth.json")
    print(format_score(score_run(DEMO_RUN, f"{DEMO_DATASET}/truth.json")) + "\n")
    report = record["summary"]["photos"][DEMO_PHOTOS[0]]["report"]
    print(f"demo finished in {time.perf_counter() - started:.0f} s; the report: {report}")
    return 0
