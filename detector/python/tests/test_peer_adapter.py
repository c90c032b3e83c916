"""eval/peers/coppertag_py.py (the peers' line protocol through the Python
package) gives the numbers of `coppertag detect --json` on the fixtures."""

from __future__ import annotations

import json
import subprocess
import sys

from conftest import REPO, fixture_paths

ADAPTER = REPO / "eval" / "peers" / "coppertag_py.py"


def test_adapter_matches_the_cli(rust_detections) -> None:
    paths = [str(p) for p in fixture_paths()]
    out = subprocess.run([sys.executable, str(ADAPTER)], input="\n".join(paths) + "\n\n",
                         capture_output=True, text=True, check=True, timeout=300)
    lines = [json.loads(line) for line in out.stdout.splitlines()]
    assert [line["image"] for line in lines] == paths
    for line in lines:
        expected = rust_detections[line["image"]]
        got = line["detections"]
        assert [(d["family"], d["id"]) for d in got] == [(e["family"], e["id"]) for e in expected]
        for d, e in zip(got, expected):
            # The protocol rounds corners to 1e-4 px.
            assert d["corners"] == [[round(x, 4), round(y, 4)] for x, y in e["corners"]]
            assert d["estimated"] == e["estimated"] and d["corrected"] == e["corrected"]
        assert line["ms"] > 0


def test_adapter_version_and_bad_path() -> None:
    version = subprocess.run([sys.executable, str(ADAPTER), "--version"], capture_output=True,
                             text=True, check=True)
    info = json.loads(version.stdout)
    assert info["detector"] == "coppertag-py" and info["package"] == "coppertag"
    assert info["version"] != "unknown"
    out = subprocess.run([sys.executable, str(ADAPTER)], input="/no/such.png\n", capture_output=True,
                         text=True, check=True)
    assert json.loads(out.stdout) == {"image": "/no/such.png", "error": "cannot read image: no such file"}
