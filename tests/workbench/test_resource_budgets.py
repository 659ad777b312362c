"""Resource budgets before work (issue 46, cause 1): a request whose size exceeds the machine is
refused from its numbers alone, with the estimate in the message, before anything is allocated.

Each probe runs the real command in its own process; its peak resident memory (its VmHWM, read by
the process itself at exit) must stay under PROBE_MEMORY_BYTES, the issue's bar: before these checks the same requests
ran until the kernel killed them (24 GB) or until time ran out.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from rcwa import load_structure
from rcwa.table import settings_for
from rcwa.table.settings import check_table_memory, table_bytes
from renderer.render import check_film_memory
from workbench.core.errors import UserInputError

PROBE_MEMORY_BYTES = 1 << 30  # the bar: under 1 GB before the refusal
CORNELL = Path(__file__).resolve().parents[2] / "renderer" / "scenes" / "cornell_cd.toml"


# The child records its own peak (VmHWM of its process image) at exit: the rusage of a child forked from a
# large test process counts the parent's pages it started with (Linux keeps the pre-exec peak).
PEAK_WRAPPER = ("import atexit, os, sys\n"
                "def peak():\n"
                "    kib = next(int(l.split()[1]) for l in open('/proc/self/status') if l.startswith('VmHWM'))\n"
                "    open(os.environ['PROBE_PEAK_FILE'], 'w').write(str(kib * 1024))\n"
                "atexit.register(peak)\n"
                "from workbench.cli import main\n"
                "sys.exit(main(sys.argv[1:]))\n")


def _run_probe(code_args: list[str], tmp_path: Path, script: str = PEAK_WRAPPER) -> tuple[int, str, int]:
    """(exit status, stderr, peak resident memory in bytes) of ``script ARGS`` in its own process."""
    peak_file = tmp_path / "peak.txt"
    run = subprocess.run([sys.executable, "-c", script, *code_args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         text=True, cwd=tmp_path, env=os.environ | {"PROBE_PEAK_FILE": str(peak_file)}, timeout=300)
    return run.returncode, run.stderr, int(peak_file.read_text())


def _probe(args: list[str], tmp_path: Path) -> tuple[int, str, int]:
    """(exit status, stderr, peak resident memory in bytes) of ``workbench ARGS`` in its own process."""
    return _run_probe(args, tmp_path)


def _big_camera(tmp_path: Path) -> str:
    text = CORNELL.read_text()
    start = text.index("resolution = [", text.index("[camera]"))
    scene = tmp_path / "big.toml"
    scene.write_text(text[:start] + "resolution = [100000, 100000]" + text[text.index("]", start) + 1:])
    return str(scene)


PROBES = {
    "theta step 0.00001 deg": (["rcwa", "table", "cd", "--out", "t.zarr", "--theta-step", "0.00001"], "--theta-step"),
    "1e8 wavelengths": (["rcwa", "table", "cd", "--out", "t.zarr", "--wavelengths", "400:700:100000000"],
                        "--wavelengths"),
    "a 2 TB table": (["rcwa", "table", "cd", "--out", "t.zarr", "--theta-step", "0.01", "--phi-step", "0.01",
                      "--wavelengths", "400:700:300"], "GiB"),
    "--resolution 100000x100000": (["render", "cornell_cd", "--out", "r.exr", "--resolution", "100000x100000"], "GiB"),
    "a scene's camera of 1e10 pixels": (["render", "{big}", "--out", "r.exr"], "camera.resolution"),
}


@pytest.mark.parametrize("name", list(PROBES))
def test_an_oversized_request_is_refused_before_work(tmp_path, name):
    args, expected = PROBES[name]
    args = [a.replace("{big}", _big_camera(tmp_path)) for a in args]
    code, err, peak = _probe(args, tmp_path)
    assert code == 2 and err.startswith("error: ") and err.strip().count("\n") == 0 and expected in err, err
    assert peak < PROBE_MEMORY_BYTES, f"{name}: {peak / 2**20:.0f} MiB before the refusal"
    assert not any(tmp_path.glob("t.zarr/*")) and not (tmp_path / "r.exr").exists()


def test_the_table_estimate_is_its_arrays_bytes():
    s = load_structure("cd")
    st = settings_for(s, "draft")
    nodes = len(st.wavelengths_nm) * len(st.theta_deg) * len(st.phi_deg)
    assert table_bytes(st) == nodes * st.keep[0] * 1 * 2 * 4  # R and T, float32, one polarization
    check_table_memory(st, total_bytes=4 * table_bytes(st))  # fits in half of four times its size
    with pytest.raises(UserInputError, match="needs about"):
        check_table_memory(st, total_bytes=table_bytes(st))


def test_the_film_estimate_scales_with_the_pixels():
    check_film_memory((978, 734), "--resolution", total_bytes=1 << 30)  # the paper's frame fits in 1 GiB
    with pytest.raises(UserInputError, match="4000 x 4000 frame"):
        check_film_memory((4000, 4000), "--resolution", total_bytes=1 << 30)


def _files(tmp_path: Path) -> dict[str, str]:
    cd = (Path(__file__).resolve().parents[2] / "rcwa" / "structures" / "cd.toml").read_text()
    many = tmp_path / "many.toml"
    many.write_text(cd + '\n[[layers]]\nthickness = 0.001\nmaterial = "polycarbonate"\n' * 100_000)
    zero_material = tmp_path / "zero_material.toml"
    zero_material.write_text('name = "z"\nperiod = [1.6]\nsuperstrate = "air"\nsubstrate = { file = "/dev/zero" }\n')
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    return {"many": str(many), "zero_material": str(zero_material), "fifo": str(fifo)}


FILE_PROBES = {
    "/dev/zero as a structure": (["rcwa", "solve", "/dev/zero", "--wavelength", "550", "--orders", "5"],
                                 "not a regular file"),
    "/dev/zero as a material": (["rcwa", "solve", "{zero_material}", "--wavelength", "550", "--orders", "5"],
                                "not a regular file"),
    "a FIFO as a structure": (["rcwa", "solve", "{fifo}", "--wavelength", "550", "--orders", "5"], "not a regular file"),
    "/dev/zero as a scene": (["render", "/dev/zero", "--out", "r.exr"], "not a regular file"),
    "100,000 layers": (["rcwa", "solve", "{many}", "--wavelength", "550", "--orders", "5"], "layers"),
}


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero on this system")
@pytest.mark.parametrize("name", list(FILE_PROBES))
def test_a_device_pipe_or_endless_file_is_refused_unread(tmp_path, name):
    """Issue 46, cause 1: /dev/zero named as a structure or material file was read whole (9.6 GB in 13 s)."""
    args, expected = FILE_PROBES[name]
    files = _files(tmp_path)
    code, err, peak = _probe([a.format(**files) if a.startswith("{") else a for a in args], tmp_path)
    assert code == 2 and err.startswith("error: ") and expected in err, err
    assert peak < PROBE_MEMORY_BYTES, f"{name}: {peak / 2**20:.0f} MiB before the refusal"


def _png_bomb(path: Path, side: int = 60000) -> None:
    """A PNG whose header declares side x side RGB pixels, with a few rows of data (kilobytes on disk)."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    rows = zlib.compress((b"\x00" + b"\x00" * (side * 3)) * 100, 9)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", side, side, 8, 2, 0, 0, 0))
                     + chunk(b"IDAT", rows) + chunk(b"IEND", b""))


@pytest.mark.parametrize("reader", ["decode", "report's render reader"])
def test_an_image_declaring_60000_square_pixels_is_refused_unread(tmp_path, reader):
    """Issue 46, cause 1: a small PNG declaring 60000 x 60000 pixels took 24 GB through `report --render`
    and a MemoryError through `decode`. The declared size is checked before the pixels are read (this
    OpenImageIO also refuses a header out of proportion to its file, whichever comes first)."""
    bomb = tmp_path / "bomb.png"
    _png_bomb(bomb)
    if reader == "decode":
        code, err, peak = _probe(["decode", str(bomb), "--out", str(tmp_path / "b.exr")], tmp_path)
    else:
        script = PEAK_WRAPPER.replace("from workbench.cli import main\nsys.exit(main(sys.argv[1:]))\n", (
            "from reports.compare.images import read_linear\nfrom workbench.core.errors import UserInputError\n"
            f"try:\n    read_linear({str(bomb)!r}, '--render')\nexcept UserInputError as e:\n"
            "    print(f'error: {e}', file=sys.stderr); sys.exit(2)\n"))
        code, err, peak = _run_probe([], tmp_path, script)
    assert code == 2 and err.startswith("error: ") and "bomb.png" in err, err
    assert peak < PROBE_MEMORY_BYTES, f"{peak / 2**20:.0f} MiB before the refusal"


def test_the_declared_size_check_refuses_what_would_not_fit():
    from calibration.raw.decode import check_image_size

    check_image_size(6000, 4000, 3, "photo.jpg", total_bytes=24 << 30)  # a 24-megapixel photo fits
    with pytest.raises(UserInputError, match="declares 60000 x 60000 pixels"):
        check_image_size(60000, 60000, 3, "bomb.png", total_bytes=24 << 30)
