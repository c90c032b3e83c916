"""Whether two `coppertag detect --json` outputs hold the same detections.

usage: same_detections.py A.jsonl B.jsonl

Each line is one image: its detections are compared as parsed (every
float the same to the bit: serde writes the shortest representation that
reads back exactly), its timing ("ms", "stats") is left out. Prints the
counts and the first images that differ; exit status 0 when every image
is in both files with the same detections, 1 when not, 2 on unreadable
input.
"""

import json
import sys


def load(path):
    """Detections by image, from one JSON line per image."""
    out = {}
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            if not line.strip():
                continue
            try:
                j = json.loads(line)
                out[j["image"]] = j["detections"]
            except (ValueError, KeyError, TypeError) as e:
                raise ValueError(f"{path}:{n}: not a detect --json line ({e})") from None
    return out


def main(argv):
    if len(argv) != 3:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    try:
        a, b = load(argv[1]), load(argv[2])
    except (OSError, ValueError) as e:
        print(f"same_detections: {e}", file=sys.stderr)
        return 2
    images = sorted(set(a) | set(b))
    differ = [k for k in images if a.get(k) != b.get(k)]
    dets = (sum(len(v) for v in a.values()), sum(len(v) for v in b.values()))
    print(f"{len(images)} images, {dets[0]} and {dets[1]} detections, {len(differ)} images differ")
    for k in differ[:5]:
        print(f"  {k}: {len(a.get(k) or [])} against {len(b.get(k) or [])} detections"
              + ("" if k in a and k in b else " (missing from one file)"))
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
