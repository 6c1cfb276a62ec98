#!/usr/bin/env python3
"""PyTorch's answer for crops: the reference the service is compared with.

    scripts/spanet/reference.py --checkpoint ckpt.pth \
        --crops a.png:wall,b.png --out DIR

For crop i writes DIR/crop<i>.canvas.png (SPANet's 144x144 input made by
the reference preprocessing: PIL LANCZOS resize of the longer side to 144,
centred paste on black) and DIR/crop<i>.txt (lines "context ...",
"action_scores ...", "skewer_points u0 v0 u1 v1", crop-normalised), the
format `bitewise-perception --check_model` writes. Eval mode throughout.
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import spanet_model as sm  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--checkpoint", required=True)
    parser.add_argument("--crops", required=True,
                        help="PATH[:isolated|wall|lettuce],...")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    try:
        model, _ = sm.load_checkpoint(args.checkpoint)
    except sm.CheckpointError as e:
        print(f"reference: checkpoint {args.checkpoint} {e}", file=sys.stderr)
        return 1
    for i, entry in enumerate(args.crops.split(",")):
        path, _, location = entry.partition(":")
        crop = sm.load_png(path)
        scores, features = sm.run_pytorch(model, crop, location or "isolated")
        stem = os.path.join(args.out, f"crop{i}")
        sm.save_png(stem + ".canvas.png", sm.canvas_uint8(crop))
        points = sm.skewer_points(scores, crop)
        with open(stem + ".txt", "w") as f:
            for name, values in (("context", features),
                                 ("action_scores", scores[4:]),
                                 ("skewer_points", points)):
                f.write(name + "".join(f" {v:.9g}" for v in values) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
