#!/usr/bin/env python3
"""Writes a randomly initialised SPANet checkpoint for tests and for trying
the export path without a trained model.

    scripts/spanet/make_test_checkpoint.py --seed 7 --out test_spanet.pth

PyTorch's default initialisation from torch.manual_seed(seed), BatchNorm's
affine parameters drawn around (1, 0), and its running statistics measured
on synthetic crops as training would leave them (so that activations keep
their scale through the network, and a model run with batch statistics,
i.e. in training mode, gives other numbers than one run in eval mode).
Saved the way training scripts save it: {"net": state_dict, "epoch": 0}.
"""

import argparse
import os
import sys

import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import spanet_model as sm  # noqa: E402


def make(seed):
    torch.manual_seed(seed)
    model = sm.SPANet()
    norms = [m for m in model.modules()
             if isinstance(m, (torch.nn.BatchNorm1d, torch.nn.BatchNorm2d))]
    with torch.no_grad():
        for norm in norms:
            norm.weight.uniform_(0.8, 1.2)
            norm.bias.uniform_(-0.1, 0.1)
            norm.reset_running_stats()
            norm.momentum = None  # a plain average over the batches below
        # Running statistics from data, as training leaves them: one pass
        # in training mode over synthetic crops at every location.
        crops = sm.synthetic_crops(seed=seed, count=8)
        rgb = torch.cat([sm.to_tensor(sm.canvas_uint8(c)) for c in crops])
        loc = torch.cat([sm.one_hot(sm.LOCATIONS[i % 3])
                         for i in range(len(crops))])
        model.train()
        model(rgb, loc)
        for norm in norms:
            norm.momentum = 0.1
            norm.num_batches_tracked.fill_(1000)
    return model.eval()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    torch.save({"net": make(args.seed).state_dict(), "epoch": 0}, args.out)
    print(f"make_test_checkpoint: wrote {args.out} (seed {args.seed})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
