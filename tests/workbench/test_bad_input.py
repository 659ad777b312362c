"""Every subcommand on a corpus of bad input: exit status 2, an ``error:`` line that says
what is wrong, and never a Python traceback (issue 13).

Runs ``workbench.cli.main`` in this process (the same code path as the command; an
escaping exception fails the test with its traceback), plus one run as a real process.
Commands added later (calibration, reports, verify) add their cases here.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from workbench.cli import main

GOOD_STRUCTURE = 'period = [1.0]\nsuperstrate = "air"\nsubstrate = "aluminum"\n'


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("bad_input")
    made = {
        "binary.toml": bytes(range(256)) * 4,
        "empty.toml": b"",
        "blank.toml": b"   \n# only a comment\n",
        "broken.toml": b"period = [1.0\n",
        "good.toml": GOOD_STRUCTURE.encode(),
        "notes.txt": b"not a table\n",
    }
    out = {}
    for name, data in made.items():
        (root / name).write_bytes(data)
        out[name] = root / name
    scene = (Path(__file__).resolve().parents[2] / "renderer" / "scenes" / "cornell_cd.toml").read_text()
    for name, table in (("misspelt.toml", '{ preset = "draft", ordres = 31 }'),
                        ("even.toml", '{ preset = "draft", orders = 20 }'),
                        ("badpreset.toml", '{ preset = "huge" }'),
                        ("keepmore.toml", '{ preset = "draft", orders = 11, keep = 21 }'),
                        ("thetarange.toml", '{ preset = "draft", theta_range = [50, 10] }'),
                        ("uv.toml", '{ preset = "draft", wavelengths = "300:700:5" }')):
        (root / name).write_text(scene.replace('table = { preset = "draft" }', f"table = {table}"))
        out[name] = root / name
    (root / "nocamera.toml").write_text(scene.split("[camera]")[0])
    out["nocamera.toml"] = root / "nocamera.toml"
    for name, fit in (("fitbounds.toml", '"cd[0].structure.period" = { bounds = [1.7, 1.8] }'),
                      ("fitrotation.toml", '"cd[0].rotation_deg" = {}')):
        (root / name).write_text(scene + f"\n[fit]\n{fit}\n")
        out[name] = root / name
    (root / "truncated.dng").write_bytes(b"II*\x00" + bytes(64))
    out["truncated.dng"] = root / "truncated.dng"
    import numpy as np
    from PIL import Image

    from datasets_synthetic.dng import DngMetadata, write_dng

    # A whole DNG as the project writes it, its image data zero below the black level but for the first row (how
    # missing data reads: LibRaw decodes it without an error; calibration.raw.checks refuses it). 64 x 48: the aspect
    # of cornell_cd's camera, so verify gets as far as the photo's samples.
    zeroed = np.zeros((48, 64), np.uint16)
    zeroed[0] = 6000
    (root / "raw_dataset" / "photos").mkdir(parents=True)
    out["zeroed.dng"] = write_dng(root / "zeroed.dng", zeroed, DngMetadata(black_level=512))
    write_dng(root / "raw_dataset" / "photos" / "zeroed.dng", zeroed, DngMetadata(black_level=512))
    out["raw_dataset"] = root / "raw_dataset"

    gradient = np.tile(np.linspace(0, 255, 64, dtype=np.uint8), (48, 1))
    for name, image in (("gray.png", gradient), ("gray2.png", gradient // 2)):
        Image.fromarray(image).save(root / name)
        out[name] = root / name
    (root / "a_folder").mkdir()
    out["a_folder"] = root / "a_folder"
    for name, board in (("undescribed_boards", None), ("bad_board_json", '{"kind": "checkerboard", "inner_corners": [9], '
                                                                         '"square_mm": 20}')):
        for sub, file_name in (("photos", "view0.png"), ("calibration", "board00.png")):
            (root / name / sub).mkdir(parents=True)
            (root / name / sub / file_name).write_bytes((root / "gray.png").read_bytes())
        if board is not None:
            (root / name / "calibration" / "board.json").write_text(board)
        out[name] = root / name
    (root / "dataset" / "photos").mkdir(parents=True)
    (root / "dataset" / "photos" / "view0.png").write_bytes((root / "gray.png").read_bytes())
    out["dataset"] = root / "dataset"
    identity = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    camera = {"width": 64, "height": 48, "fx": 60, "fy": 60, "cx": 32, "cy": 24, "world_to_camera": {"view0.png": identity}}
    for name, calibration in (("run_unfinished", None), ("run_no_camera", {"camera": {"world_to_camera": {}}}),
                              ("run_done", {"camera": camera})):
        (root / name / "calibration").mkdir(parents=True)
        status = "running" if calibration is None else "done"
        (root / name / "run.json").write_text(json.dumps({"format": "workbench-verify",
                                                          "stages": {"calibration": {"status": status}}}))
        if calibration is not None:
            (root / name / "calibration" / "calibration.json").write_text(json.dumps(calibration))
        out[name] = root / name
    truths = {"truth_camera_list.json": {"camera": [], "sensor": {}, "light_power_scale": 1, "exposure_time_s": {},
                                         "response": {}},
              "truth_no_fx.json": {"camera": {k: v for k, v in camera.items() if k != "fx"}, "sensor": {},
                                   "light_power_scale": 1, "exposure_time_s": {}, "response": {}},
              "truth_other_photos.json": {"camera": camera | {"world_to_camera": {"view9.png": identity}}, "sensor": {},
                                          "light_power_scale": 1, "exposure_time_s": {}, "response": {}}}
    for name, truth in truths.items():
        (root / name).write_text(json.dumps(truth))
        out[name] = root / name
    out["root"] = root
    return out


CASES: list[tuple[str, list[str], str]] = [
    # (case id, argv with {placeholders} for the files above, a phrase the message must hold)
    ("solve-binary", ["rcwa", "solve", "{binary.toml}", "--wavelength", "500", "--orders", "5"], "not a text file"),
    ("solve-empty", ["rcwa", "solve", "{empty.toml}", "--wavelength", "500", "--orders", "5"], "is empty"),
    ("solve-blank", ["rcwa", "solve", "{blank.toml}", "--wavelength", "500", "--orders", "5"], "is empty"),
    ("solve-broken", ["rcwa", "solve", "{broken.toml}", "--wavelength", "500", "--orders", "5"], "not valid TOML"),
    ("solve-missing-file", ["rcwa", "solve", "{root}/nosuch.toml", "--wavelength", "500", "--orders", "5"], "not found"),
    ("solve-folder", ["rcwa", "solve", "{a_folder}/", "--wavelength", "500", "--orders", "5"], "folder"),
    ("solve-unknown-builtin", ["rcwa", "solve", "nosuch", "--wavelength", "500", "--orders", "5"], "no such structure"),
    ("solve-even-orders", ["rcwa", "solve", "cd", "--wavelength", "500", "--orders", "4"], "odd"),
    ("solve-orders-beyond-memory", ["rcwa", "solve", "cd", "--wavelength", "500", "--orders", "100001"], "GiB"),
    ("table-orders-beyond-memory", ["rcwa", "table", "cd", "--out", "{root}/t7.zarr", "--orders", "100001",
                                    "--wavelengths", "500", "--theta-step", "45", "--phi-step", "45"], "GiB"),
    ("table-wavelength-outside-data", ["rcwa", "table", "cd", "--out", "{root}/t6.zarr", "--wavelengths", "100:700:11"],
     "polycarbonate"),
    ("solve-orders-not-int", ["rcwa", "solve", "cd", "--wavelength", "500", "--orders", "many"], "expected N"),
    ("solve-wavelength-outside-data", ["rcwa", "solve", "cd", "--wavelength", "100", "--orders", "5"], "superstrate"),
    ("solve-negative-wavelength", ["rcwa", "solve", "cd", "--wavelength", "-5", "--orders", "5"], "wavelength"),
    ("solve-theta-over-90", ["rcwa", "solve", "cd", "--wavelength", "500", "--theta", "95", "--orders", "5"], "theta"),
    ("table-bad-wavelengths", ["rcwa", "table", "cd", "--out", "{root}/t1.zarr", "--wavelengths", "700:400:3"], "wavelengths"),
    ("table-even-orders", ["rcwa", "table", "cd", "--out", "{root}/t2.zarr", "--orders", "20"], "odd"),
    ("table-keep-more", ["rcwa", "table", "cd", "--out", "{root}/t3.zarr", "--orders", "11", "--keep-orders", "21"], "keep"),
    ("table-threads", ["rcwa", "table", "cd", "--out", "{root}/t4.zarr", "--preset", "draft", "--threads", "0"], "threads"),
    ("table-binary", ["rcwa", "table", "{binary.toml}", "--out", "{root}/t5.zarr"], "not a text file"),
    ("info-not-a-table", ["rcwa", "info", "{a_folder}"], "not an efficiency table"),
    ("info-missing", ["rcwa", "info", "{root}/nosuch.zarr"], "not an efficiency table"),
    ("render-binary", ["render", "{binary.toml}", "--out", "{root}/r.exr"], "not a text file"),
    ("render-empty", ["render", "{empty.toml}", "--out", "{root}/r.exr"], "is empty"),
    ("render-missing", ["render", "{root}/nosuch.toml", "--out", "{root}/r.exr"], "not found"),
    ("render-unknown-builtin", ["render", "nosuch", "--out", "{root}/r.exr"], "no such scene"),
    ("render-misspelt-table-key", ["render", "{misspelt.toml}", "--out", "{root}/r.exr"], "cd[0].table.ordres"),
    ("render-even-table-orders", ["render", "{even.toml}", "--out", "{root}/r.exr"], "cd[0].table.orders"),
    ("render-bad-table-preset", ["render", "{badpreset.toml}", "--out", "{root}/r.exr"], "cd[0].table.preset"),
    ("render-table-keep-more-than-orders", ["render", "{keepmore.toml}", "--out", "{root}/r.exr"],
     "keepmore.toml: field 'cd[0].table.keep'"),
    ("render-table-theta-range", ["render", "{thetarange.toml}", "--out", "{root}/r.exr"], "field 'cd[0].table.theta_range'"),
    ("render-table-wavelength-outside-data", ["render", "{uv.toml}", "--out", "{root}/r.exr"],
     "uv.toml: field 'cd[0].table.wavelengths': material 'polycarbonate'"),
    ("plan-table-wavelength-outside-data", ["plan", "{uv.toml}"], "uv.toml: field 'cd[0].table.wavelengths'"),
    ("plan-table-keep-more-than-orders", ["plan", "{keepmore.toml}"], "field 'cd[0].table.keep'"),
    ("render-no-camera", ["render", "{nocamera.toml}", "--out", "{root}/r.exr"], "camera"),
    ("render-spp-zero", ["render", "cornell_cd", "--out", "{root}/r.exr", "--spp", "0"], "--spp"),
    ("render-seed-negative", ["render", "cornell_cd", "--out", "{root}/r.exr", "--seed", "-1"], "--seed"),
    ("render-not-exr", ["render", "cornell_cd", "--out", "{root}/r.png"], ".exr"),
    ("render-bad-resolution", ["render", "cornell_cd", "--out", "{root}/r.exr", "--resolution", "0x5"], "WxH"),
    ("synth-seed-negative", ["synth", "cornell_cd", "--out", "{root}/d", "--seed", "-1"], "--seed"),
    ("synth-out-is-a-file", ["synth", "cornell_cd", "--out", "{notes.txt}"], "--out"),
    ("synth-bad-preset", ["synth", "cornell_cd", "--out", "{root}/d", "--preset", "huge"], "--preset"),
    ("synth-binary-scene", ["synth", "{binary.toml}", "--out", "{root}/d"], "not a text file"),
    ("study-rcwa-missing", ["study", "rcwa", "{root}/nosuch.toml", "--out", "{root}/s"], "not found"),
    ("study-rcwa-2d-even-orders", ["study", "rcwa", "gold2d", "--out", "{root}/s", "--max-orders", "24"], "odd"),
    ("study-render-missing", ["study", "render", "{root}/nosuch.toml", "--out", "{root}/s"], "not found"),
    ("plan-binary", ["plan", "{binary.toml}"], "not a text file"),
    ("plan-missing", ["plan", "{root}/nosuch.toml"], "not found"),
    ("plan-misspelt-table-key", ["plan", "{misspelt.toml}"], "cd[0].table.ordres"),
    ("fit-bounds-exclude-nominal", ["fit", "{a_folder}", "--scene", "{fitbounds.toml}", "--calibration", "{root}/c.json",
                                    "--out", "{root}/f1"], "fitbounds.toml: field 'fit.cd[0].structure.period.bounds'"),
    ("fit-rotation-not-identifiable", ["fit", "{a_folder}", "--scene", "{fitrotation.toml}", "--calibration",
                                       "{root}/c.json", "--out", "{root}/f2"], "not identifiable"),
    ("fit-dataset-without-photos", ["fit", "{a_folder}", "--scene", "cornell_cd", "--calibration", "{root}/c.json",
                                    "--out", "{root}/f3"], "photos"),
    ("fit-renders-not-a-folder", ["fit", "{a_folder}", "--scene", "cornell_cd", "--calibration", "{root}/c.json",
                                  "--out", "{root}/f", "--renders", "{root}/nosuch"], "field '--renders'"),
    ("fit-zero-supersample", ["fit", "{a_folder}", "--scene", "cornell_cd", "--calibration", "{root}/c.json",
                              "--out", "{root}/f4", "--supersample", "0"], "--supersample"),
    ("study-fit-bad-truth-scene", ["study", "fit", "{a_folder}", "--scene", "cornell_cd", "--calibration",
                                   "{root}/c.json", "--truth-scene", "{root}/nosuch.toml", "--out", "{root}/sf"],
     "nosuch.toml"),
    ("decode-missing", ["decode", "{root}/nosuch.dng", "--out", "{root}/o.exr"], "nosuch.dng"),
    ("decode-not-an-image", ["decode", "{notes.txt}", "--out", "{root}/o.exr"], "notes.txt"),
    ("decode-truncated-raw", ["decode", "{truncated.dng}", "--out", "{root}/o.exr"], "truncated.dng"),
    ("decode-zeroed-raw", ["decode", "{zeroed.dng}", "--out", "{root}/o.exr"], "zeroed.dng: damaged image data"),
    ("intrinsics-bad-board", ["calibrate", "intrinsics", "{gray.png}", "--board", "9by6", "--square-mm", "25",
                              "--out", "{root}/i.json"], "--board"),
    ("intrinsics-too-few-views", ["calibrate", "intrinsics", "{gray.png}", "--board", "9x6", "--square-mm", "25",
                                  "--out", "{root}/i.json"], "view"),
    ("intrinsics-negative-square", ["calibrate", "intrinsics", "{gray.png}", "--board", "9x6", "--square-mm", "-2",
                                    "--out", "{root}/i.json"], "--square-mm"),
    ("response-one-image", ["calibrate", "response", "{gray.png}", "--out", "{root}/r.json"], "2"),
    ("response-no-exposure-times", ["calibrate", "response", "{gray.png}", "{gray2.png}", "--out", "{root}/r.json"],
     "exposure"),
    ("response-times-count", ["calibrate", "response", "{gray.png}", "{gray2.png}", "--times", "0.01",
                              "--out", "{root}/r.json"], "--times"),
    ("response-bad-times", ["calibrate", "response", "{gray.png}", "{gray2.png}", "--times", "0.01,fast",
                            "--out", "{root}/r.json"], "--times"),
    ("pose-missing-photo", ["calibrate", "pose", "{root}/nosuch.dng", "--scene", "cornell_cd", "--out", "{root}/p"],
     "nosuch.dng"),
    ("pose-zeroed-raw-photo", ["calibrate", "pose", "{zeroed.dng}", "--scene", "cornell_cd", "--out", "{root}/p"],
     "zeroed.dng: damaged image data"),
    ("pose-scene-without-camera", ["calibrate", "pose", "{gray.png}", "--scene", "{nocamera.toml}", "--out", "{root}/p"],
     "camera"),
    ("dataset-without-photos", ["calibrate", "dataset", "{a_folder}", "--scene", "cornell_cd", "--out", "{root}/c"],
     "photos"),
    ("dataset-zeroed-raw-photo", ["calibrate", "dataset", "{raw_dataset}", "--scene", "cornell_cd", "--out",
                                  "{root}/c6"], "zeroed.dng: damaged image data"),
    ("calibrate-dataset-short-form", ["calibrate", "{a_folder}", "--scene", "cornell_cd", "--out", "{root}/c2"], "photos"),
    ("dataset-board-undescribed", ["calibrate", "{undescribed_boards}", "--scene", "cornell_cd", "--out", "{root}/c3"],
     "board.json"),
    ("dataset-board-square-missing", ["calibrate", "{undescribed_boards}", "--scene", "cornell_cd", "--out", "{root}/c4",
                                      "--board", "9x6"], "--square-mm"),
    ("dataset-board-json-bad-field", ["calibrate", "{bad_board_json}", "--scene", "cornell_cd", "--out", "{root}/c5"],
     "field 'inner_corners'"),
    ("study-calibrate-without-truth", ["study", "calibrate", "{undescribed_boards}", "--scene", "cornell_cd", "--out",
                                       "{root}/s2"], "truth.json"),
    ("study-calibrate-bad-scale", ["study", "calibrate", "{undescribed_boards}", "--scene", "cornell_cd", "--out",
                                   "{root}/s3", "--scales", "1,half"], "--scales"),
    ("report-missing-calibration", ["report", "--photo", "{gray.png}", "--render", "{gray.png}", "--calibration",
                                    "{root}/c.json", "--scene", "cornell_cd", "--out", "{root}/rep"], "--calibration"),
    ("report-missing-photo", ["report", "--photo", "{root}/nosuch.dng", "--render", "{root}/r.exr", "--calibration",
                              "{run_done}/calibration/calibration.json", "--scene", "cornell_cd", "--out", "{root}/rep"],
     "--photo"),
    ("report-binary-photo", ["report", "--photo", "{binary.toml}", "--render", "{gray.png}", "--calibration",
                             "{run_done}/calibration/calibration.json", "--scene", "cornell_cd", "--out", "{root}/rep"],
     "cannot be read as an image"),
    ("report-truncated-raw-photo", ["report", "--photo", "{truncated.dng}", "--render", "{gray.png}", "--calibration",
                                    "{run_done}/calibration/calibration.json", "--scene", "cornell_cd", "--out",
                                    "{root}/rep"], "truncated.dng"),
    ("report-zeroed-raw-photo", ["report", "--photo", "{zeroed.dng}", "--render", "{gray.png}", "--calibration",
                                 "{run_done}/calibration/calibration.json", "--scene", "cornell_cd", "--out",
                                 "{root}/rep"], "zeroed.dng: damaged image data"),
    ("report-jpeg-without-response", ["report", "--photo", "{gray.png}", "--render", "{gray.png}", "--calibration",
                                      "{run_done}/calibration/calibration.json", "--scene", "cornell_cd", "--out",
                                      "{root}/rep"], "response"),
    ("report-binary-scene", ["report", "--photo", "{gray.png}", "--render", "{gray.png}", "--calibration",
                             "{run_done}/calibration/calibration.json", "--scene", "{binary.toml}", "--out", "{root}/rep"],
     "not a text file"),
    ("report-out-is-a-file", ["report", "--photo", "{gray.png}", "--render", "{gray.png}", "--calibration",
                              "{run_done}/calibration/calibration.json", "--scene", "cornell_cd", "--out", "{notes.txt}"],
     "--out"),
    ("verify-missing-dataset", ["verify", "{root}/nosuch", "--scene", "cornell_cd", "--out", "{root}/v1"], "no such dataset"),
    ("verify-dataset-is-a-file", ["verify", "{notes.txt}", "--scene", "cornell_cd", "--out", "{root}/v1"], "dataset"),
    ("verify-without-photos", ["verify", "{a_folder}", "--scene", "cornell_cd", "--out", "{root}/v1"], "no photos"),
    ("verify-binary-scene", ["verify", "{dataset}", "--scene", "{binary.toml}", "--out", "{root}/v1"], "not a text file"),
    ("verify-missing-scene", ["verify", "{dataset}", "--scene", "{root}/nosuch.toml", "--out", "{root}/v1"], "not found"),
    ("verify-out-is-a-file", ["verify", "{dataset}", "--scene", "cornell_cd", "--out", "{notes.txt}"], "--out"),
    ("verify-out-holds-other-files", ["verify", "{dataset}", "--scene", "cornell_cd", "--out", "{undescribed_boards}"],
     "no verify run wrote"),
    ("verify-unknown-photo", ["verify", "{dataset}", "--scene", "cornell_cd", "--out", "{root}/v1", "--photo", "nosuch.png"],
     "--photo"),
    ("verify-zeroed-raw-photo", ["verify", "{raw_dataset}", "--scene", "cornell_cd", "--out", "{root}/v2"],
     "zeroed.dng: damaged image data"),
    ("verify-spp-zero", ["verify", "{dataset}", "--scene", "cornell_cd", "--out", "{root}/v1", "--spp", "0"], "--spp"),
    ("verify-seed-negative", ["verify", "{dataset}", "--scene", "cornell_cd", "--out", "{root}/v1", "--seed", "-1"], "--seed"),
    ("verify-bad-board", ["verify", "{dataset}", "--scene", "cornell_cd", "--out", "{root}/v1", "--board", "9"], "--board"),
    ("score-not-a-run", ["score", "{a_folder}", "--truth", "{root}/truth.json"], "not a verify run"),
    ("score-unfinished-run", ["score", "{run_unfinished}", "--truth", "{root}/truth.json"], "not finished"),
    ("score-calibration-without-camera", ["score", "{run_no_camera}", "--truth", "{root}/truth.json"], "camera.width"),
    ("score-missing-truth", ["score", "{run_done}", "--truth", "{root}/nosuch.json"], "cannot read the truth"),
    ("score-binary-truth", ["score", "{run_done}", "--truth", "{binary.toml}"], "not JSON"),
    ("score-truth-of-another-kind", ["score", "{run_done}", "--truth", "{run_done}/run.json"], "not a synthetic dataset"),
    ("score-truth-camera-not-an-object", ["score", "{run_done}", "--truth", "{truth_camera_list.json}"], "'camera'"),
    ("score-truth-without-fx", ["score", "{run_done}", "--truth", "{truth_no_fx.json}"], "camera.fx"),
    ("score-truth-of-other-photos", ["score", "{run_done}", "--truth", "{truth_other_photos.json}"], "view0.png"),
    ("demo-cache-is-a-file", ["demo", "--cache", "{notes.txt}"], "--cache"),
    ("cache-list-cache-is-a-file", ["cache", "list", "--cache", "{notes.txt}"], "--cache"),
    ("cache-clear-cache-is-a-file", ["--cache", "{notes.txt}", "cache", "clear"], "--cache"),
    ("render-workers-zero", ["render", "cornell_cd", "--out", "{root}/r.exr", "--workers", "0"], "--workers"),
    ("table-workers-zero", ["rcwa", "table", "cd", "--out", "{root}/t8.zarr", "--preset", "draft", "--workers", "0"],
     "--workers"),
    ("table-bad-theta-range", ["rcwa", "table", "cd", "--out", "{root}/t9.zarr", "--theta-range", "0"], "LO,HI"),
    ("solve-bad-pol", ["rcwa", "solve", "cd", "--wavelength", "500", "--orders", "5", "--pol", "circular"], "invalid choice"),
    ("study-render-binary", ["study", "render", "{binary.toml}", "--out", "{root}/s"], "not a text file"),
    ("study-rcwa-binary", ["study", "rcwa", "{binary.toml}", "--out", "{root}/s"], "not a text file"),
    ("plan-empty", ["plan", "{empty.toml}"], "is empty"),
    ("decode-bad-demosaic", ["decode", "{gray.png}", "--out", "{root}/o.exr", "--demosaic", "magic"], "invalid choice"),
    ("cache-unknown-action", ["cache", "shred"], "invalid choice"),
    ("list-unknown-kind", ["list", "gizmos"], "invalid choice"),
    ("unknown-command", ["frobnicate"], "invalid choice"),
]


def _expand(argv: list[str], files: dict[str, Path]) -> list[str]:
    out = []
    for arg in argv:
        for key, path in files.items():
            arg = arg.replace("{" + key + "}", str(path))
        out.append(arg)
    return out


@pytest.mark.parametrize(("argv", "phrase"), [(c[1], c[2]) for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_a_clear_error(argv: list[str], phrase: str, files: dict[str, Path],
                                    capsys: pytest.CaptureFixture[str]) -> None:
    code: int | str | None
    try:
        code = main(_expand(argv, files))
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert "error:" in err and phrase in err, err
    assert "Traceback" not in err


def test_a_bad_input_as_a_real_process_prints_no_traceback(files: dict[str, Path]) -> None:
    run = subprocess.run([sys.executable, "-m", "workbench.cli", "rcwa", "solve", str(files["binary.toml"]),
                          "--wavelength", "500", "--orders", "5"], capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and run.stderr.startswith("error:") and "Traceback" not in run.stderr, run.stderr


def test_nothing_is_left_behind_by_refused_table_requests(files: dict[str, Path]) -> None:
    """Validation comes before writing: refused table requests create no output folder."""
    leftovers = sorted(p.name for p in files["root"].iterdir() if p.name.startswith("t") and p.suffix == ".zarr")
    assert not leftovers, leftovers


def _leaf_commands(parser, path: tuple[str, ...] = ()):
    import argparse

    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield path
    for action in subs:
        for name, sub in action.choices.items():
            yield from _leaf_commands(sub, (*path, name))


def test_the_corpus_covers_every_subcommand() -> None:
    """Each command the parser knows (``rcwa solve``, ``calibrate pose``, ``cache clear``...)
    has at least one case above, so a command added later without bad-input cases fails here."""
    from workbench.cli import _build_parser

    def covers(argv: list[str], leaf: tuple[str, ...]) -> bool:
        words = [a for a in argv if not a.startswith("-") and "{" not in a]
        return tuple(words[:len(leaf)]) == leaf

    uncovered = [" ".join(leaf) for leaf in _leaf_commands(_build_parser())
                 if not any(covers(argv, leaf) for _, argv, _ in CASES)]
    assert not uncovered, f"subcommands without a bad-input case: {uncovered}"
