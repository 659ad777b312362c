"""What the suite asserts of `calibrate DATASET` on its one seeded dataset, and why not the
issue's bars themselves (issue 23).

The suite calibrates one realisation: the seed-0 draft dataset of cornell_cd, whose renders
carry Monte Carlo noise. Over 12 realisations of that dataset's renders (synth's
``render_seed``: the same hidden camera, poses and sensor noise streams; measured with
``python -m benchmarks.bench_calibration --seeds 0 --render-seeds 1,...,11``) the worst
photo's errors were, mean +- SD (largest):

    rotation            0.065 +- 0.031 deg  (0.143)  issue 14's bar 0.1 deg: missed by 1 of 12
    camera centre       0.46 +- 0.26 mm     (1.08)   bar 1 mm: missed by 1 of 12
    field of view       0.012 +- 0.0095 deg (0.038)  bar 0.05 deg
    principal point     0.18 +- 0.077 %     (0.36)   bar 0.5 %
    exposure x light    0.12 +- 0.020 %     (0.15)   bar 1 %
    response RMS        0.047 +- 0.027 %    (0.13)   bar 1 %

so asserting the 0.1 deg and 1 mm bars on one realisation is a pass by luck of the draw
(about 1 in 6 realisations misses one), and the field of view's and principal point's bars
sit 4 SD out (a 1e-3 false-alarm rate by Student's t, below). The bars stay the product's
and are judged over realisations in benchmarks/bench_calibration.py (its --render-seeds
spread); the tests assert each error below its mean plus K SD with K = 7.39, Student's t
predictive bound for one more realisation with 11 degrees of freedom at 1e-5 (the SD
itself estimated from 12 draws): about 1e-5 per bound, six bounds, under 1e-4 for them all.
They still fail a calibration gone wrong (errors of degrees and centimetres, or a 3x
regression of the rotation), and the reported standard deviations are held honest by
test_pose's STD_FACTOR check. Exposure and response keep the issue's 1 % (35-44 SD out).
"""

ROTATION_DEG = 0.29  # 0.065 + 7.39 x 0.031
CENTRE_MM = 2.4  # 0.46 + 7.39 x 0.26
FOV_DEG = 0.082  # 0.012 + 7.39 x 0.0095
PRINCIPAL_POINT_PCT = 0.75  # 0.18 + 7.39 x 0.077
EXPOSURE_PCT = 1.0  # issue 14's bar, 44 SD out
RESPONSE_RMS_PCT = 1.0  # issue 14's bar, 35 SD out
