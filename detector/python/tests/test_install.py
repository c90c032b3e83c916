"""The wheel installed into a fresh venv, imported with nothing from the
source tree on the path."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO

WHEELS = REPO / "target" / "wheels"

SCRIPT = """
import pathlib, sys
import numpy as np
import coppertag
root = pathlib.Path(sys.prefix).resolve()
assert pathlib.Path(coppertag.__file__).resolve().is_relative_to(root), coppertag.__file__
assert not any(p and pathlib.Path(p).resolve() == pathlib.Path(sys.argv[1]).resolve() for p in sys.path)
img = np.pad(coppertag.generate("ct14", 113, px=200), 30, constant_values=255)
found = coppertag.Detector().detect(img)
assert [(d.family, d.id) for d in found] == [("ct14", 113)], found
package = pathlib.Path(coppertag.__file__).parent
assert (package / "__init__.pyi").exists() and (package / "py.typed").exists(), list(package.iterdir())
print("ok", coppertag.__version__)
"""


def test_fresh_venv(tmp_path: Path) -> None:
    wheels = sorted(WHEELS.glob("coppertag-*.whl"))
    if len(wheels) != 1:
        pytest.fail(f"expected one wheel in {WHEELS} (run `make wheel`), found {wheels}")
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    py = venv / "bin" / "python"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    # The same numpy as the project's venv, so pip finds it in its cache.
    subprocess.run(
        [str(py), "-m", "pip", "install", "--quiet", "--disable-pip-version-check", str(wheels[0]),
         f"numpy=={np.__version__}"],
        check=True, env=env, cwd=tmp_path,
    )
    out = subprocess.run([str(py), "-I", "-c", SCRIPT, str(REPO)], capture_output=True, text=True,
                         env=env, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("ok ")
