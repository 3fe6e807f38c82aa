#!/usr/bin/env python3
"""How many of a reference detector's boxes another detector finds, frame by frame.

Both inputs are detections.json files written by `mcslam detect` on the same images (for
example the reference yolov8n_640.onnx and yolov8n_320.onnx at --input-size 224x192). A
reference box is found when a box of the same class overlaps it with IoU >= 0.5 (each candidate
box matches one reference box at most). Prints, per candidate file, the share of the reference's
people found, the median and 10th-percentile IoU of those found, and the share found over all
classes.

Usage: scripts/detector_recall.py REFERENCE.json CANDIDATE.json [CANDIDATE.json ...]
"""
import json
import sys


def frames_of(path):
    with open(path) as f:
        data = json.load(f)
    return [frame["detections"] for frame in data["frames"]]


def iou(a, b):
    ax, ay, aw, ah = a["box"]
    bx, by, bw, bh = b["box"]
    w = max(0.0, min(ax + aw, bx + bw) - max(ax, bx))
    h = max(0.0, min(ay + ah, by + bh) - max(ay, by))
    inter = w * h
    union = aw * ah + bw * bh - inter
    return inter / union if union > 0 else 0.0


def match(reference, candidate, classes=None):
    """IoU of each reference box's best free same-class candidate (0 when none)."""
    found = []
    for ref_boxes, cand_boxes in zip(reference, candidate):
        used = set()
        for r in ref_boxes:
            if classes and r["class"] not in classes:
                continue
            best, best_j = 0.0, -1
            for j, c in enumerate(cand_boxes):
                if j in used or c["class"] != r["class"]:
                    continue
                v = iou(r, c)
                if v > best:
                    best, best_j = v, j
            if best >= 0.5:
                used.add(best_j)
            found.append(best)
    return found


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    reference = frames_of(sys.argv[1])
    for path in sys.argv[2:]:
        candidate = frames_of(path)
        if len(candidate) != len(reference):
            sys.exit(f"{path}: {len(candidate)} frames, the reference has {len(reference)}")
        people = match(reference, candidate, {"person"})
        hits = sorted(v for v in people if v >= 0.5)
        every = match(reference, candidate)
        if not people or not hits:
            print(f"{path}: no reference people found")
            continue
        print(f"{path}: people {len(hits) / len(people):.3f} ({len(hits)}/{len(people)}), "
              f"IoU median {hits[len(hits) // 2]:.3f} p10 {hits[len(hits) // 10]:.3f}; "
              f"all classes {sum(v >= 0.5 for v in every) / len(every):.3f}")


if __name__ == "__main__":
    main()
