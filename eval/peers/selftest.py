"""End-to-end check of the peer adapters against markers rendered from the committed codebooks.

Usage (from the repository root):

    .venv/bin/python eval/peers/selftest.py [--keep DIR]

For each peer system the markers are rendered here, in numpy, from
``synth/data/peers/*.json`` only (no detector-side drawing code): every output
pixel is the mean of 8x8 point samples of the ideal black/white marker, so
edges are anti-aliased. Coordinates are pixel-centre coordinates: pixel i
spans [i - 0.5, i + 0.5]. The marker is placed through an exact homography
from its unit square (the outer black square) to four known image points, so
upright, rotated by 90/180/270 degrees and perspective-warped markers all
have exactly known corners. (Sampling the homography analytically is the
same as warpPerspective of an infinitely fine render, followed by a box
downsample.)

The images go through each adapter as a subprocess speaking the line protocol,
and the script asserts ids, the physical corner order (TL, BL, BR, TR of the
upright marker) and a corner error below 0.5 px; it also checks the error
lines for a missing file and a garbage file. It prints a summary table and
exits non-zero on any failure.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

HERE = Path(__file__).resolve().parent
CODEBOOKS = HERE.parents[1] / "synth" / "data" / "peers"
SUPERSAMPLE = 8
# A pixel-convention error shows up as a mean offset of ~0.5 px; this catches it.
MEAN_TOLERANCE_PX = 0.15

# A marker is a predicate on its unit square coordinates (u right, v down;
# the outer black square is [0, 1]^2): True where the marker is black.
MarkerFn = Callable[[np.ndarray, np.ndarray], np.ndarray]


# ---------------------------------------------------------------- rendering


def square_marker(code: list[int], bits: int, border: int) -> MarkerFn:
    """Black-square marker with a ``bits`` x ``bits`` data grid (row-major, 1 = black)."""
    cells = bits + 2 * border
    grid = np.ones((cells, cells), dtype=bool)
    grid[border : border + bits, border : border + bits] = np.array(code, dtype=bool).reshape(bits, bits)

    def fn(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        inside = (u >= 0) & (u < 1) & (v >= 0) & (v < 1)
        col = np.clip((u * cells).astype(np.int64), 0, cells - 1)
        row = np.clip((v * cells).astype(np.int64), 0, cells - 1)
        return inside & grid[row, col]

    return fn


def stag_marker(code: list[int], geometry: dict, texels: int = 4096) -> MarkerFn:
    """STag marker: black square, white disc, black code circles plus fillers (geometry in units of E).

    The interior is painted once into a ``texels`` x ``texels`` mask over the
    unit square (1/4096 E, well under 0.1 px at the sizes tested) and looked
    up; the square's outer edges are tested exactly.
    """
    centres = np.array(geometry["code_centres"], dtype=np.float64)
    black = [i for i, bit in enumerate(code) if bit]
    circles = [(centres[i], geometry["code_circle_radius"]) for i in black]
    for a_pos, a in enumerate(black):
        for b in black[a_pos + 1 :]:
            if np.linalg.norm(centres[a] - centres[b]) < geometry["filler_max_centre_distance"]:
                circles.append(((centres[a] + centres[b]) / 2, geometry["filler_radius"]))
    axis = (np.arange(texels) + 0.5) / texels
    cx, cy = geometry["inner_disc_centre"]
    mask = (axis[None, :] - cx) ** 2 + (axis[:, None] - cy) ** 2 > geometry["inner_disc_radius"] ** 2
    for (px, py), r in circles:
        lo_x, hi_x = max(int((px - r) * texels), 0), min(int((px + r) * texels) + 2, texels)
        lo_y, hi_y = max(int((py - r) * texels), 0), min(int((py + r) * texels) + 2, texels)
        du = axis[None, lo_x:hi_x] - px
        dv = axis[lo_y:hi_y, None] - py
        mask[lo_y:hi_y, lo_x:hi_x] |= du * du + dv * dv <= r * r

    def fn(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        inside = (u >= 0) & (u < 1) & (v >= 0) & (v < 1)
        col = np.clip((u * texels).astype(np.int64), 0, texels - 1)
        row = np.clip((v * texels).astype(np.int64), 0, texels - 1)
        return inside & mask[row, col]

    return fn


def fractal_marker(rows: list[str], occluded_corner: float = 0.0) -> MarkerFn:
    """Fractal marker from its committed cell bitmap (row-major, '1' = black).

    With ``occluded_corner`` > 0 a black patch covers the square
    [-0.2, occluded_corner]^2 of the unit square (over the TL corner and its
    quiet zone), so the outer square's outline is broken and only the inner
    levels can be found.
    """
    grid = np.array([[ch == "1" for ch in row] for row in rows], dtype=bool)
    cells = grid.shape[0]

    def fn(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        inside = (u >= 0) & (u < 1) & (v >= 0) & (v < 1)
        col = np.clip((u * cells).astype(np.int64), 0, cells - 1)
        row = np.clip((v * cells).astype(np.int64), 0, cells - 1)
        black = inside & grid[row, col]
        if occluded_corner > 0:
            patch = (u >= -0.2) & (u < occluded_corner) & (v >= -0.2) & (v < occluded_corner)
            black |= patch
        return black

    return fn


def render(size: tuple[int, int], marker: MarkerFn, corners: np.ndarray, rows_per_chunk: int = 16) -> np.ndarray:
    """Render one marker into a white ``size`` = (width, height) uint8 image.

    ``corners`` are the image positions (pixel-centre coordinates) of the
    marker's TL, BL, BR, TR corners, i.e. of unit points (0,0), (0,1), (1,1), (1,0).
    Each pixel is the mean of SUPERSAMPLE x SUPERSAMPLE point samples.
    """
    width, height = size
    h_img_from_unit = homography(np.array([[0, 0], [0, 1], [1, 1], [1, 0]], dtype=np.float64), corners)
    h = np.linalg.inv(h_img_from_unit)
    image = np.full((height, width), 255.0)
    x0 = max(int(math.floor(corners[:, 0].min())) - 2, 0)
    x1 = min(int(math.ceil(corners[:, 0].max())) + 3, width)
    y0 = max(int(math.floor(corners[:, 1].min())) - 2, 0)
    y1 = min(int(math.ceil(corners[:, 1].max())) + 3, height)
    offsets = (np.arange(SUPERSAMPLE) + 0.5) / SUPERSAMPLE - 0.5
    xs = (np.arange(x0, x1)[:, None] + offsets[None, :]).ravel()
    for r0 in range(y0, y1, rows_per_chunk):
        r1 = min(r0 + rows_per_chunk, y1)
        ys = (np.arange(r0, r1)[:, None] + offsets[None, :]).ravel()
        gx, gy = np.meshgrid(xs, ys)
        w = h[2, 0] * gx + h[2, 1] * gy + h[2, 2]
        u = (h[0, 0] * gx + h[0, 1] * gy + h[0, 2]) / w
        v = (h[1, 0] * gx + h[1, 1] * gy + h[1, 2]) / w
        black = marker(u, v).reshape(r1 - r0, SUPERSAMPLE, x1 - x0, SUPERSAMPLE)
        image[r0:r1, x0:x1] = 255.0 * (1.0 - black.mean(axis=(1, 3)))
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def homography(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """3x3 homography (h33 = 1) mapping four ``src`` points onto four ``dst`` points, in float64."""
    rows, rhs = [], []
    for (x, y), (u, v) in zip(src, dst, strict=True):
        rows.append([x, y, 1, 0, 0, 0, -u * x, -u * y])
        rows.append([0, 0, 0, x, y, 1, -v * x, -v * y])
        rhs += [u, v]
    sol = np.linalg.solve(np.array(rows, dtype=np.float64), np.array(rhs, dtype=np.float64))
    return np.append(sol, 1.0).reshape(3, 3)


def placed_corners(
    origin: tuple[float, float], side: float, quarter_turns: int, warp: np.ndarray | None = None
) -> np.ndarray:
    """Image positions of TL, BL, BR, TR for an axis-aligned square rotated clockwise on screen.

    The outer black square spans ``origin`` to ``origin + side``; the marker is
    turned by ``quarter_turns`` x 90 degrees clockwise (as seen on screen) about
    its centre, then ``warp`` (4x2 pixel displacements) is added.
    """
    ox, oy = origin
    upright = np.array([[ox, oy], [ox, oy + side], [ox + side, oy + side], [ox + side, oy]])
    # Corners are listed counter-clockwise on screen; a clockwise quarter turn
    # moves the marker's corner i to the screen position of upright corner i - 1
    # (TL goes to where TR was, BL to where TL was, ...).
    turned = np.array([upright[(i - quarter_turns) % 4] for i in range(4)])
    return turned + (0 if warp is None else warp)


# ---------------------------------------------------------------- test plan


@dataclass
class System:
    """One peer system: adapter script, family name and a marker factory."""

    name: str
    adapter: str
    family: str
    ids: list[int]
    side: float
    make: Callable[[int], MarkerFn]
    canvas: tuple[int, int]
    tolerance: float  # largest allowed distance of one corner from truth, px
    corrected: int | None  # expected "corrected" value on a clean render
    # Extra cases with the outer square's TL corner covered (fractal only):
    # (label, marker factory); the adapter must report estimated corners.
    occluded: Callable[[int], MarkerFn] | None = None


@dataclass
class Case:
    """One rendered image with its truth."""

    system: str
    label: str
    marker_id: int
    path: Path
    truth: np.ndarray
    estimated: bool = False


@dataclass
class Result:
    """Per-system tallies for the summary table."""

    cases: int = 0
    found: int = 0
    order_ok: int = 0
    errors: list[np.ndarray] = field(default_factory=list)
    max_err: float = 0.0
    estimated_max_err: float = 0.0
    ms: list[float] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)


def load_systems() -> list[System]:
    """Read the committed codebooks and describe the three systems."""
    april = json.loads((CODEBOOKS / "tag36h11.json").read_text())
    mip = json.loads((CODEBOOKS / "aruco_mip_36h12.json").read_text())
    stag = json.loads((CODEBOOKS / "stag_hd21.json").read_text())
    fractal = json.loads((CODEBOOKS / "fractal_5l_6.json").read_text())

    def ends(count: int) -> list[int]:
        return [0, count // 2, count - 1]

    return [
        System(
            name="apriltag3",
            adapter="apriltag3.py",
            family="tag36h11",
            ids=ends(len(april["codes"])),
            side=160.0,
            make=lambda i: square_marker(april["codes"][i], april["bits"], april["border_bits"]),
            canvas=(400, 420),
            tolerance=0.5,
            corrected=0,
        ),
        System(
            name="aruco3",
            adapter="aruco3.py",
            family="aruco_mip_36h12",
            ids=ends(len(mip["codes"])),
            side=160.0,
            make=lambda i: square_marker(mip["codes"][i], mip["bits"], mip["border_bits"]),
            canvas=(400, 420),
            # Default Aruco3 parameters skip sub-pixel refinement (see aruco3.py):
            # corners are integer contour vertices, up to ~1.1 px off.
            tolerance=1.25,
            corrected=None,
        ),
        System(
            name="stag",
            adapter="stag.py",
            family="stag_hd21",
            ids=ends(len(stag["codes"])),
            side=300.0,
            make=lambda i: stag_marker(stag["codes"][i], stag["geometry"]),
            canvas=(540, 560),
            # STag's corners are quantised to the pixel grid: up to 0.5 px per
            # axis when the square's edges fall on pixel boundaries.
            tolerance=0.8,
            corrected=None,
        ),
        System(
            name="fractal",
            adapter="fractal.py",
            family="fractal_5l_6",
            # One marker (id 0), placed at each of the three sub-pixel origins.
            ids=[0, 0, 0],
            side=312.0,
            make=lambda _i: fractal_marker(fractal["rows"]),
            canvas=(560, 580),
            tolerance=FRACTAL_TOLERANCE_PX,
            corrected=None,
            occluded=lambda _i: fractal_marker(fractal["rows"], occluded_corner=FRACTAL_PATCH),
        ),
    ]


# Fractal corners: sub-pixel refined by the library (cornerSubPix); observed
# mean 0.15 px, max 0.26 px on these renders. Extrapolated (outer square hidden,
# corners through the homography of the inner levels' points): up to
# FRACTAL_ESTIMATED_TOLERANCE_PX.
FRACTAL_TOLERANCE_PX = 0.35
FRACTAL_ESTIMATED_TOLERANCE_PX = 0.6
# Far corner of the black patch over the TL corner in the occluded fractal
# cases, unit-square coordinates: past the outer level's border (1/13 =
# 0.077), short of level 1 (which starts at 0.308).
FRACTAL_PATCH = 0.25

WARPS = [
    np.array([[6.0, -4.0], [-5.0, 3.0], [4.0, 7.0], [-3.0, -6.0]]),
    np.array([[-8.0, 5.0], [3.0, -2.0], [-4.0, -6.0], [9.0, 4.0]]),
    np.array([[10.0, 8.0], [0.0, 0.0], [-12.0, 6.0], [2.0, -7.0]]),
]


# Sub-pixel origins of the outer black square, one per tested id: edges through
# pixel centres, on pixel boundaries, and in between.
ORIGINS = [(100.0, 120.0), (100.5, 120.5), (100.25, 119.8)]


def build_cases(systems: list[System], out_dir: Path) -> list[Case]:
    """Render every test image to ``out_dir`` and return the cases.

    Per id: the four quarter turns at that id's origin, plus one perspective
    warp of a turned placement.
    """
    cases = []
    for system in systems:
        for idx, marker_id in enumerate(system.ids):
            marker = system.make(marker_id)
            origin = ORIGINS[idx % len(ORIGINS)]
            variants = [(f"rot{90 * k}", placed_corners(origin, system.side, k)) for k in range(4)]
            turns = idx + 1
            warped = placed_corners((origin[0] + 0.3, origin[1] - 0.3), system.side, turns, WARPS[idx % len(WARPS)])
            variants.append((f"persp+rot{90 * turns}", warped))
            for label, truth in variants:
                path = out_dir / f"{system.name}_{marker_id}_{idx}_{label}.png"
                cv2.imwrite(str(path), render(system.canvas, marker, truth))
                cases.append(Case(system.name, label, marker_id, path, truth))
            if system.occluded is not None:
                hidden = system.occluded(marker_id)
                for k in (0, turns % 4):
                    truth = placed_corners(origin, system.side, k, WARPS[idx % len(WARPS)] if k else None)
                    label = f"occluded-tl+rot{90 * k}"
                    path = out_dir / f"{system.name}_{marker_id}_{idx}_{label}.png"
                    cv2.imwrite(str(path), render(system.canvas, hidden, truth))
                    cases.append(Case(system.name, label, marker_id, path, truth, estimated=True))
    return cases


# ---------------------------------------------------------------- running


def run_adapter(adapter: str, lines: list[str]) -> tuple[list[dict], int, str]:
    """Feed ``lines`` to an adapter over stdin; return parsed stdout lines, exit code, stderr."""
    proc = subprocess.run(
        [sys.executable, str(HERE / adapter)],
        input="".join(line + "\n" for line in lines),
        capture_output=True,
        text=True,
        timeout=600,
    )
    records = [json.loads(line) for line in proc.stdout.splitlines()]
    return records, proc.returncode, proc.stderr


def check_system(system: System, cases: list[Case], scratch: Path) -> Result:
    """Run one adapter over its cases plus the error-handling probes, and score it."""
    result = Result()
    missing = str(scratch / "does_not_exist.png")
    garbage = scratch / "garbage.png"
    garbage.write_bytes(bytes(range(256)) * 7)
    empty = scratch / "empty.jpg"
    empty.write_bytes(b"")
    probes = [missing, str(garbage), str(empty)]
    # Probes are interleaved with real images and an empty line to check the loop keeps going.
    lines = (
        [missing]
        + [str(c.path) for c in cases[:1]]
        + ["", str(garbage), "   ", str(empty)]
        + [str(c.path) for c in cases[1:]]
    )
    records, code, stderr = run_adapter(system.adapter, lines)
    expected = [ln for ln in lines if ln.strip()]
    if code != 0:
        result.failures.append(f"exit code {code}: {stderr.strip()[-300:]}")
    if len(records) != len(expected):
        result.failures.append(f"{len(records)} output lines for {len(expected)} inputs")
        return result
    for rec, path in zip(records, expected, strict=True):
        if rec.get("image") != path:
            result.failures.append(f"line for {path} names {rec.get('image')}")
    by_path = {rec["image"]: rec for rec in records}
    for probe in probes:
        if "error" not in by_path[probe] or "detections" in by_path[probe]:
            result.failures.append(f"no error line for {Path(probe).name}: {by_path[probe]}")

    for case in cases:
        result.cases += 1
        rec = by_path[str(case.path)]
        tag = f"{case.path.name}"
        if "error" in rec:
            result.failures.append(f"{tag}: error {rec['error']}")
            continue
        if not isinstance(rec.get("ms"), float) or rec["ms"] < 0:
            result.failures.append(f"{tag}: bad ms {rec.get('ms')}")
            continue
        result.ms.append(rec["ms"])
        hits = [d for d in rec["detections"] if d["id"] == case.marker_id and d["family"] == system.family]
        if len(hits) != 1 or len(rec["detections"]) != 1:
            ids = [(d["family"], d["id"]) for d in rec["detections"]]
            result.failures.append(f"{tag}: expected one {system.family} id {case.marker_id}, got {ids}")
            continue
        det = hits[0]
        result.found += 1
        got = np.array(det["corners"], dtype=np.float64)
        if (
            got.shape != (4, 2)
            or det["estimated"] != [case.estimated] * 4
            or det["corrected"] != system.corrected
        ):
            result.failures.append(f"{tag}: malformed detection {det}")
            continue
        # Physical order: each reported corner must be nearest to its own truth corner.
        dists = np.linalg.norm(got[:, None, :] - case.truth[None, :, :], axis=2)
        if not np.array_equal(dists.argmin(axis=1), np.arange(4)):
            result.failures.append(f"{tag}: corner order {dists.argmin(axis=1).tolist()} (want [0,1,2,3])")
            continue
        result.order_ok += 1
        err = got - case.truth
        worst = float(np.linalg.norm(err, axis=1).max())
        tolerance = FRACTAL_ESTIMATED_TOLERANCE_PX if case.estimated else system.tolerance
        if case.estimated:
            result.estimated_max_err = max(result.estimated_max_err, worst)
        else:
            result.errors.append(err)
            result.max_err = max(result.max_err, worst)
        if worst > tolerance:
            result.failures.append(f"{tag}: corner error {worst:.3f} px > {tolerance}: {np.round(err, 3).tolist()}")
    if result.errors:
        mean = np.concatenate(result.errors).mean(axis=0)
        if np.abs(mean).max() > MEAN_TOLERANCE_PX:
            result.failures.append(f"mean corner offset {np.round(mean, 3).tolist()} exceeds {MEAN_TOLERANCE_PX} px")
    return result


def check_version(system: System) -> str:
    """Run ``--version`` and return the reported version string."""
    out = subprocess.run(
        [sys.executable, str(HERE / system.adapter), "--version"], capture_output=True, text=True, timeout=60
    )
    info = json.loads(out.stdout.strip())
    assert info["detector"] == system.name, info
    return f"{info['package']} {info['version']}"


def summarise(system: System, result: Result, version: str) -> str:
    """One row of the summary table."""
    if result.errors:
        errs = np.concatenate(result.errors)
        mean = errs.mean(axis=0)
        mean_abs = float(np.linalg.norm(errs, axis=1).mean())
    else:
        mean, mean_abs = np.array([math.nan, math.nan]), math.nan
    ms = float(np.median(result.ms)) if result.ms else math.nan
    status = "PASS" if not result.failures else "FAIL"
    return (
        f"{system.name:<10} {version:<42} {result.found:>2}/{result.cases:<2} {result.order_ok:>2}/{result.cases:<2}"
        f" {mean[0]:+7.3f} {mean[1]:+7.3f} {mean_abs:7.3f} {result.max_err:7.3f} {system.tolerance:5.2f}"
        f" {ms:7.2f}  "
        + (f"(estimated corners: max|e| {result.estimated_max_err:.3f}) " if system.occluded else "")
        + status
    )


def main() -> int:
    """Render, run, check and print the summary; return the process exit code."""
    parser = argparse.ArgumentParser(description="Self-test of the peer adapters.")
    parser.add_argument("--keep", type=Path, help="write the rendered images here and keep them")
    args = parser.parse_args()
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="peers-selftest-") as tmp:
        scratch = args.keep or Path(tmp)
        scratch.mkdir(parents=True, exist_ok=True)
        systems = load_systems()
        cases = build_cases(systems, scratch)
        rows, failures = [], []
        for system in systems:
            version = check_version(system)
            result = check_system(system, [c for c in cases if c.system == system.name], scratch)
            rows.append(summarise(system, result, version))
            failures += [f"{system.name}: {f}" for f in result.failures]
    print(
        f"{'system':<10} {'package':<42} {'found':<5} {'order':<5} {'mean dx':>7} {'mean dy':>7}"
        f" {'mean|e|':>7} {'max|e|':>7} {'tol':>5} {'med ms':>7}  result"
    )
    print("\n".join(rows))
    print(
        f"(corner error = reported - truth in pixel-centre coordinates; |mean dx|, |mean dy| must be"
        f" <= {MEAN_TOLERANCE_PX} px, every corner's |e| <= tol; {time.perf_counter() - start:.1f} s)"
    )
    for failure in failures:
        print("FAIL", failure)
    passed = sum(1 for r in rows if r.endswith("PASS"))
    print(f"selftest: {passed} passed, {len(rows) - passed} failed")
    return 0 if not failures else 1


if __name__ == "__main__":
    sys.exit(main())
