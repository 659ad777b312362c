"""What the suite asserts of the report and the scene fit on the shared seed-0 dataset, and
why not issue 15's bars and issue 25's verdict themselves (issue 23).

The suite's report and fit tests read one realisation of the seed-0 draft dataset's renders
(Monte Carlo noise). Over 12 realisations (synth's ``render_seed`` 0-11: the same hidden
camera, poses, exposures and sensor noise streams; measured with ``python -m
benchmarks.bench_realisations --work DIR --render-seeds 0,...,11``, which recomputes each
quantity with the tests' own code) they were, mean +- SD (range):

tests/reports/test_report_synthetic.py (truth camera, a render of another seed):
    photo-render median         0.205 +- 0.040 px (0.14-0.27)   issue 15's bar 0.5 px at 7.4 SD
    photo-render p95            1.15 +- 0.23 px (0.85-1.62)     bar 1.5 px: missed by 1 of 12
    band edges paired           108 +- 10 (89-125)              at least 8
    prediction-render median    0.260 +- 0.044 px               bar 0.5 px at 5.5 SD
    prediction-photo median     0.290 +- 0.054 px (0.22-0.42)   bar 0.5 px at 3.9 SD
    its edges                   62 +- 9.2 (46-77)               at least 5 (the report's own threshold)
    known turn 0.3 deg          0.372 +- 0.029 px (0.31-0.42)   bar 0.5 px at 4.4 SD
    known FOV +0.2 deg          0.268 +- 0.047 px               bar 0.5 px at 5.0 SD
tests/workbench/test_verify.py (verify at 4 spp, its own calibration; remeasured after issue 25's
last fit changes: band edges along circles and radii as separate noise groups, the leverage cap
and the outlier rule, the joint camera covariance; the 4-spp renders are too noisy for the
forward model's offsets, so none is taken off, and the report says so):
    verdict                     consistent 11, model 1 (realisation 6: the period 0.77 % off at 4.4
                                of its std 0.0028 um; before these changes consistent on all 12)
    Wald statistic (5 dof)      6.7 +- 6.9 (largest 23.5)
    fitted - file, period       0.0017 +- 0.0091 um (0.6 %; was 0.0019 +- 0.013)
    tilt e1, e2                 -0.071 +- 0.118 deg, 0.044 +- 0.139 deg (was 0.049, 0.058: the
                                noise groups weigh the radius edges, which carry the tilt, by their
                                measured scatter; one group gives realisation 6 half its tilt move)
    light x, z                  -1.3 +- 1.9 mm, -0.78 +- 1.7 mm (was 0.93, 1.1)
tests/calibration/test_pose.py (errors in their reported standard deviations, worst photo):
    rotation 1.47 +- 0.76, camera centre 0.79 +- 0.44, cx 1.21 +- 1.17 (to 3.48), cy 1.95 +- 0.76 (to 3.47)
    (the 12 realisations before: 1.10 +- 0.50, 0.74 +- 0.42, 0.71 +- 0.57, 1.51 +- 0.89 to 3.46)

so the bars and the verdict, asserted on one realisation, pass by the luck of the draw (the
p95 bar fails 1 realisation in 12; the verdict failed 2 in 12 before the band bootstrap, and
even a calibrated test calls a consistent scene otherwise at its alpha, 1e-3, plus the
file-median rule's 2e-3 (0.298 +- 0.055 px against 0.5). They stay the product's and are
judged over realisations in the benchmark; the tests assert each quantity within its mean
plus K SD, K = 9.41, Student's t predictive bound for one more realisation with 11 degrees
of freedom at 1e-6 (the SD itself estimated from 12 draws): about 1e-6 per bound, 12 bounds
here. Counts keep their thresholds (6.2-17 SD, normal tails < 1e-9: a count is a sum of
many edges). They still fail a report or a fit gone wrong (a median of pixels, a period
off by 6 %, a tilt of 1.4 degrees, a light moved 2 cm); the fit's are looser than before its
noise groups (a tilt of half a degree), which the perturbed cases of benchmarks/bench_scene_fit
(with the forward model's offsets measured) check instead.
"""

K = 9.41  # t.isf(1e-6, 11) * sqrt(1 + 1/12)

# tests/reports/test_report_synthetic.py
PAIR_MEDIAN_PX = 0.58  # 0.205 + K x 0.040
PAIR_P95_PX = 3.3  # 1.15 + K x 0.233
PREDICTION_RENDER_MEDIAN_PX = 0.67  # 0.260 + K x 0.0438
PREDICTION_PHOTO_MEDIAN_PX = 0.80  # 0.290 + K x 0.054
KNOWN_ERROR_MEDIAN_PX = {"rotated 0.3 deg": 0.64, "FOV +0.2 deg": 0.71}  # 0.372 + K x 0.0288; 0.268 + K x 0.0466

# tests/workbench/test_verify.py: |fitted - file value| per component (|mean| + K SD)
FIT_MOVE = {
    "cd[0].structure.period:value": 0.088,  # um: 0.0017 + K x 0.0091
    "cd[0].normal:tilt_e1": 1.19,  # deg: 0.071 + K x 0.118
    "cd[0].normal:tilt_e2": 1.36,  # deg: 0.044 + K x 0.139
    "light.center:x": 0.019,  # m: 0.0013 + K x 0.0019
    "light.center:z": 0.0166,  # m: 0.00078 + K x 0.0017
}

# tests/calibration/test_pose.py: errors in reported standard deviations; cx's mean + K SD (12.3)
# is the largest (rotation 8.6, centre 4.9, cy 9.1)
STD_FACTOR = 12.5
