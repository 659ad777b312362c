"""docs/mitsuba_plugin.md's examples, run as written (issue 49, item 4).

Its first Python block builds a coarse CD table and renders a disk with the bwdf plugin in
a plain ``mi.load_dict`` scene; its XML block is the same scene for ``mi.load_file``. Both
must render a lit image whose CD shows colour (the orders spread the lamp's white light by
wavelength: some pixel's channels differ by more than half their mean, which a grey or
black surface cannot give). An RGB variant must be refused by name, with the spectral
variants listed, before any render."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np

DOC = Path(__file__).resolve().parents[2] / "docs" / "mitsuba_plugin.md"


def _block(language: str) -> str:
    match = re.search(rf"```{language}\n(.*?)```", DOC.read_text(), re.S)
    assert match is not None, f"docs/mitsuba_plugin.md has no {language} block"
    return match.group(1)


def _run(code: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True, timeout=600)


def _coloured(image: np.ndarray) -> bool:
    rgb = np.clip(image[..., :3], 0, None)
    mean = rgb.mean(axis=-1)
    lit = mean > 0.05 * mean.max()
    return bool(np.any((rgb.max(axis=-1) - rgb.min(axis=-1))[lit] > 0.5 * mean[lit]))


def test_the_dict_and_xml_examples_render_a_coloured_cd(tmp_path: Path) -> None:
    example = _block("python")
    proc = _run(example + "\nnp.save('dict.npy', image)\n", tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "cd.exr").is_file()
    image = np.load(tmp_path / "dict.npy")
    assert image.shape == (64, 96, 3) and np.all(np.isfinite(image)) and image.max() > 0
    assert _coloured(image)

    (tmp_path / "cd_scene.xml").write_text(_block("xml"))
    proc = _run("import mitsuba as mi, numpy as np\nfrom renderer.plugins import register_plugins\n"
                "from renderer.variant import set_variant\nset_variant()\nregister_plugins()\n"
                "np.save('xml.npy', np.array(mi.render(mi.load_file('cd_scene.xml'), spp=16)))\n", tmp_path)
    assert proc.returncode == 0, proc.stderr
    from_xml = np.load(tmp_path / "xml.npy")
    assert from_xml.shape == image.shape and _coloured(from_xml)
    # the same scene and seed in both forms: the same image, up to the film's summation order
    np.testing.assert_allclose(from_xml, image, rtol=1e-4, atol=1e-5 * float(image.max()))


def test_an_rgb_variant_is_refused_by_name(tmp_path: Path) -> None:
    proc = _run("import mitsuba as mi\nmi.set_variant('scalar_rgb')\nfrom renderer.plugins import register_plugins\n"
                "register_plugins()\n", tmp_path)
    assert proc.returncode != 0
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("RuntimeError:") and "'scalar_rgb'" in last, last
    assert all(v in last for v in ("scalar_spectral", "llvm_ad_spectral", "cuda_ad_spectral")), last
