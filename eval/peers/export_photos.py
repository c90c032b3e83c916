"""Export natural photographs shipped with scikit-image as grey PNGs.

Usage (from the repository root, inside the peers venv):

    .venv/bin/python eval/peers/export_photos.py OUT_DIR

The tag-free false-positive set ``datasets/wild/fp-photos.toml`` crops,
scales and rotates these photographs into frames (``coppertag synth
datasets/wild/fp-photos.toml -o DIR [--photos OUT_DIR]``). They are the
sample images bundled inside the scikit-image wheel (``skimage.data``),
so nothing is downloaded; the version is pinned in
``eval/peers/requirements.txt`` and recorded in ``OUT_DIR/photos.json``.

Only photographs of real scenes are exported (people, animals, objects,
textures, text on paper, sky, microscope and fundus images); the
synthetic images of ``skimage.data`` (checkerboard, colour wheel, logo,
phantoms, binary masks) are left out, because a false-positive set of
natural images should not hold drawn squares.

Colour photographs become grey with integer Rec. 709 luma weights
(``(2126 R + 7152 G + 722 B + 5000) // 10000``), so the grey levels do not
depend on a floating-point library: the same scikit-image version gives
the same pixels, and ``coppertag synth`` the same frames.

The directory is written atomically: the files go to a hidden directory
beside OUT_DIR, which is renamed into place at the end. An existing
OUT_DIR is replaced only when it is empty or an earlier export (it holds
``photos.json``). Exit 2 with a one-line message on a bad OUT_DIR.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from importlib import metadata
from pathlib import Path

import numpy as np

MANIFEST = "photos.json"

# (file stem, skimage.data function, what it shows). Every one ships inside
# the scikit-image wheel (no download).
PHOTOS: list[tuple[str, str, str]] = [
    ("astronaut", "astronaut", "portrait of astronaut Eileen Collins"),
    ("brick", "brick", "brick wall texture"),
    ("camera", "camera", "man with a camera on a tripod, outdoors"),
    ("cell", "cell", "cell under a microscope"),
    ("chelsea", "chelsea", "a cat"),
    ("clock", "clock", "a wall clock, motion-blurred"),
    ("coffee", "coffee", "a cup of coffee on a table"),
    ("coins", "coins", "coins on a dark background"),
    ("grass", "grass", "grass texture"),
    ("gravel", "gravel", "gravel texture"),
    ("hubble_deep_field", "hubble_deep_field", "Hubble deep field, galaxies"),
    ("immunohistochemistry", "immunohistochemistry", "stained tissue under a microscope"),
    ("moon", "moon", "surface of the moon"),
    ("page", "page", "a printed page of text, unevenly lit"),
    ("retina", "retina", "fundus photograph of a retina"),
    ("rocket", "rocket", "a rocket on its launch pad"),
    ("stereo_motorcycle", "stereo_motorcycle", "a motorcycle in a workshop (left image of a stereo pair)"),
    ("text", "text", "handwritten and printed text on a sign"),
]

# Rec. 709 luma weights, times 10000 (integer arithmetic).
LUMA_709 = (2126, 7152, 722)
LUMA_SCALE = 10000


class ExportError(Exception):
    """A problem with the output directory or an image; exit 2."""


def to_grey(image: np.ndarray, name: str) -> np.ndarray:
    """An 8-bit grey image from an 8-bit grey, RGB or RGBA array."""
    if image.dtype != np.uint8:
        raise ExportError(f"{name}: expected 8-bit pixels, got {image.dtype}")
    if image.ndim == 2:
        return image
    if image.ndim == 3 and image.shape[2] in (3, 4):
        rgb = image[:, :, :3].astype(np.int64)
        weights = np.array(LUMA_709, dtype=np.int64)
        grey = (rgb @ weights + LUMA_SCALE // 2) // LUMA_SCALE
        return np.clip(grey, 0, 255).astype(np.uint8)
    raise ExportError(f"{name}: unexpected image shape {image.shape}")


def load(function: str) -> np.ndarray:
    """One photograph from skimage.data (the first of a stereo pair)."""
    from skimage import data

    image = getattr(data, function)()
    if isinstance(image, tuple):
        image = image[0]
    return np.asarray(image)


def check_target(out: Path) -> None:
    """Raise ExportError unless `out` may be written or replaced."""
    parent = out.parent
    if not parent.is_dir():
        raise ExportError(f"{out}: the parent directory {parent} does not exist")
    if out.exists() and not out.is_dir():
        raise ExportError(f"{out}: exists and is not a directory")
    if out.is_dir() and any(out.iterdir()) and not (out / MANIFEST).is_file():
        raise ExportError(f"{out}: exists, is not empty and is not an earlier export (no {MANIFEST}); not replacing it")


def export(out: Path) -> int:
    """Write every photograph and the manifest into `out`; the count."""
    from PIL import Image

    check_target(out)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent))
    try:
        manifest = {
            "source": "skimage.data",
            "scikit_image": metadata.version("scikit-image"),
            "grey": "integer Rec. 709 luma: (2126 R + 7152 G + 722 B + 5000) // 10000",
            "photos": [],
        }
        for stem, function, what in PHOTOS:
            grey = to_grey(load(function), stem)
            Image.fromarray(grey, mode="L").save(tmp / f"{stem}.png", format="PNG")
            manifest["photos"].append(
                {"file": f"{stem}.png", "function": f"skimage.data.{function}", "shows": what,
                 "width": int(grey.shape[1]), "height": int(grey.shape[0])}
            )
        (tmp / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
        tmp.chmod(0o755)  # mkdtemp makes it private
        old = None
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", suffix=".tmp", dir=out.parent))
            old.rmdir()
            out.rename(old)
        tmp.rename(out)
        if old is not None:
            shutil.rmtree(old)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return len(PHOTOS)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path, help="directory to write (created; an earlier export is replaced)")
    args = parser.parse_args(argv)
    try:
        n = export(args.out_dir)
    except ExportError as e:
        print(f"export_photos: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"export_photos: {args.out_dir}: {e}", file=sys.stderr)
        return 2
    print(f"export_photos: {n} photographs -> {args.out_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
