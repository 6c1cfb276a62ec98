#!/usr/bin/env python3
"""Exports a trained SPANet checkpoint to the ONNX file the PerceptionService
serves, and refuses to write a file that disagrees with PyTorch.

    scripts/spanet/export_onnx.py --checkpoint spanet_ckpt.pth --out spanet.onnx

1. Loads the checkpoint on the CPU (a state_dict, {"net": state_dict, ...},
   or a pickled module; a "module." prefix is removed) and checks it key by
   key against SPANet's RGB path: missing keys, unknown keys, wrong shapes,
   non-finite values and non-positive BatchNorm variances are refused, each
   named.
2. Exports in eval mode (BatchNorm from running statistics) with the
   service's interface: inputs "rgb" [1,3,144,144], "loc_type" [1,3];
   outputs "features" [1,2048], "scores" [1,10]; opset 11, batch fixed at 1.
3. Runs the exported file through the service's own loader and Featurize
   (bitewise-perception --check_model) on a few crops of odd and even sizes,
   portrait and landscape, at each location, and compares with PyTorch:
   SPANet's 144x144 input canvas pixel for pixel, and features, action
   scores and skewer points within --tolerance relative (max |difference| /
   max |PyTorch value|, per vector).
4. Only then moves the file to --out.
5. Writes the context scale beside it, <out>.stats (E||c||^2 of the model's
   features on seen foods, which sets a new user's context ridge), with
   bitewise-featurizer-stats: about 2 minutes on two cores for 400 plates
   (--stats_plates). --no_stats skips it and prints the command instead.
Exit 0: written; 1: refused (the message says why) or the statistics could
not be written (the model stays); 2: bad arguments.

The binaries are looked for in --build_dir (default $BITEWISE_BUILD_DIR, else
the checkout's build/), then on PATH (an installed bitewise).

--check_onnx FILE skips the export and runs steps 1 and 3 on an ONNX file
made some other way (for example by hand, or with training mode left on).
Run it with Debian's python3 (python3-torch, python3-pil, python3-numpy).
"""

import argparse
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import spanet_model as sm  # noqa: E402

DEFAULT_BUILD_DIR = os.environ.get("BITEWISE_BUILD_DIR") or os.path.join(
    os.path.dirname(os.path.abspath(__file__)), "..", "..", "build")


def find_binary(build_dir, relative):
    """The build tree's binary, else one on PATH, else None."""
    path = os.path.join(build_dir, relative)
    if os.path.exists(path):
        return path
    return shutil.which(os.path.basename(relative))


class _Interface(torch.nn.Module):
    """(rgb, loc_type) -> (scores, features): the names the service wants."""

    def __init__(self, spanet):
        super().__init__()
        self.spanet = spanet

    def forward(self, rgb, loc_type):
        return self.spanet(rgb, loc_type)


def materialize_shared_initializers(path):
    """Replaces each Identity node on an initializer by a copy of it.

    PyTorch's exporter writes a weight that is used more than once (SPANet
    reuses conv_layers_bot three times) or that equals another (BatchNorm
    parameters at their initial values) once, and the other uses as
    Identity nodes; OpenCV 4.6's importer cannot run Identity on a
    constant. The values are unchanged.
    """
    import onnx  # python3-onnx; only the export needs it
    model = onnx.load(path)
    graph = model.graph
    initializers = {t.name: t for t in graph.initializer}
    keep = []
    for node in graph.node:
        if node.op_type == "Identity" and node.input[0] in initializers:
            copy = graph.initializer.add()
            copy.CopyFrom(initializers[node.input[0]])
            copy.name = node.output[0]
        else:
            keep.append(node)
    del graph.node[:]
    graph.node.extend(keep)
    onnx.save(model, path)


def export(model, path):
    model.eval()
    # The wrapper must be in eval mode too: the exporter restores the
    # wrapper's mode, recursively, when it is done.
    torch.onnx.export(
        _Interface(model).eval(),
        (torch.zeros(1, 3, sm.IMAGE_SIZE, sm.IMAGE_SIZE),
         sm.one_hot("isolated")),
        path, opset_version=11, do_constant_folding=True,
        training=torch.onnx.TrainingMode.EVAL,
        input_names=["rgb", "loc_type"], output_names=["scores", "features"])
    materialize_shared_initializers(path)


def compare(model, onnx_path, binary, crops, tolerance, out=sys.stdout):
    """Compares the service's outputs with PyTorch; returns the failures."""
    locations = [sm.LOCATIONS[i % 3] for i in range(len(crops))]
    service = sm.run_service(binary, onnx_path, crops, locations)
    failures = []
    print(f"{'crop (h x w)':>14} {'location':>9} {'canvas px differing':>20} "
          f"{'features':>9} {'scores':>9} {'points':>9}", file=out)
    for crop, location, got in zip(crops, locations, service):
        canvas = sm.canvas_uint8(crop)
        differing = int(np.count_nonzero(
            np.any(canvas != got["canvas"], axis=-1)))
        scores, features = sm.run_pytorch(model, crop, location)
        errors = {
            "features": sm.relative_error(got["context"], features),
            "action scores": sm.relative_error(got["action_scores"],
                                               scores[4:]),
            "skewer points": sm.relative_error(got["skewer_points"],
                                               sm.skewer_points(scores, crop)),
        }
        size = f"{crop.shape[0]} x {crop.shape[1]}"
        print(f"{size:>14} {location:>9} {differing:>20} "
              f"{errors['features']:9.2e} {errors['action scores']:9.2e} "
              f"{errors['skewer points']:9.2e}", file=out)
        if differing:
            failures.append(f"{size} crop: the service's 144x144 input differs "
                            f"from the reference preprocessing in {differing} "
                            "pixels")
        off = [f"{name} by {error:.2e}" for name, error in errors.items()
               if not error <= tolerance]
        if off:
            failures.append(f"{size} crop at {location}: {', '.join(off)} "
                            f"relative (tolerance {tolerance:g})")
    return failures


def write_stats(args):
    """<out>.stats with bitewise-featurizer-stats, or the command to run."""
    stats = args.out + ".stats"
    tool = find_binary(args.build_dir, os.path.join(
        "experiments", "bitewise-featurizer-stats"))
    command = [tool or "bitewise-featurizer-stats", "--featurizer=spanet",
               f"--spanet_model={args.out}", f"--plates={args.stats_plates}",
               f"--out={stats}"]
    if args.no_stats or tool is None:
        why = ("--no_stats" if args.no_stats else
               f"bitewise-featurizer-stats not found in {args.build_dir} "
               "nor on PATH")
        print(f"export_onnx: {why}: no {stats} written. Without it the "
              "PerceptionService warns at start and new users get the "
              "BanditService's default context ridge. Write it with "
              f"(about 2 minutes on two cores):\n  {' '.join(command)}")
        return 0 if args.no_stats else 1
    print(f"export_onnx: writing {stats} ({args.stats_plates} plates of "
          "seen foods; about 2 minutes on two cores at 400)", flush=True)
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        print(f"export_onnx: could not write {stats}: {done.stderr.strip()}",
              file=sys.stderr)
        return 1
    print(f"export_onnx: {done.stdout.strip().splitlines()[-1]}")
    return 0


def main():
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--checkpoint", required=True,
                        help="PyTorch checkpoint (.pth) of SPANet")
    parser.add_argument("--out", help="ONNX file to write")
    parser.add_argument("--check_onnx",
                        help="compare this existing ONNX file instead of "
                             "exporting")
    parser.add_argument("--build_dir", default=DEFAULT_BUILD_DIR,
                        help="where to find bitewise-perception and "
                             "bitewise-featurizer-stats (default: "
                             "$BITEWISE_BUILD_DIR or the checkout's build/; "
                             "then PATH)")
    parser.add_argument("--perception_binary",
                        help="bitewise-perception (default: from --build_dir)")
    parser.add_argument("--no_stats", action="store_true",
                        help="do not write <out>.stats (print the command)")
    parser.add_argument("--stats_plates", type=int, default=400,
                        help="plates of seen foods for <out>.stats")
    parser.add_argument("--crops", default="",
                        help="comma-separated PNG crops to compare on "
                             "(default: eight synthetic crops)")
    parser.add_argument("--tolerance", type=float, default=1e-4)
    args = parser.parse_args()
    if bool(args.out) == bool(args.check_onnx):
        parser.error("give exactly one of --out and --check_onnx")
    if args.perception_binary is None:
        args.perception_binary = find_binary(
            args.build_dir, os.path.join("services", "perception",
                                         "bitewise-perception"))
    if args.perception_binary is None or not os.path.exists(
            args.perception_binary):
        parser.error("bitewise-perception not found in "
                     f"{args.build_dir} nor on PATH; build it "
                     "(scripts/setup.sh), or pass --build_dir or "
                     "--perception_binary")

    def refuse(why):
        print(f"export_onnx: refused: {why}", file=sys.stderr)
        return 1

    try:
        model, notes = sm.load_checkpoint(args.checkpoint)
    except sm.CheckpointError as e:
        return refuse(f"checkpoint {args.checkpoint} {e}")
    for note in notes:
        print(f"export_onnx: note: {note}", file=sys.stderr)
    crops = ([sm.load_png(p) for p in args.crops.split(",")] if args.crops
             else sm.synthetic_crops(count=8))

    target = args.check_onnx
    tmp = None
    if args.out:
        directory = os.path.dirname(os.path.abspath(args.out))
        fd, tmp = tempfile.mkstemp(prefix=".spanet-export-", suffix=".onnx",
                                   dir=directory)
        os.close(fd)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        export(model, tmp)
        target = tmp
    try:
        try:
            failures = compare(model, target, args.perception_binary, crops,
                               args.tolerance)
        except sm.ServiceCheckError as e:
            return refuse(str(e))
        if failures:
            return refuse(
                "the ONNX model does not reproduce PyTorch in eval mode "
                "(a graph exported with BatchNorm in training mode, another "
                "architecture or other weights differ this way):\n  " +
                "\n  ".join(failures))
        if args.out:
            os.replace(tmp, args.out)
            tmp = None
            print(f"export_onnx: wrote {args.out} (checked on {len(crops)} "
                  f"crops, tolerance {args.tolerance:g})")
            return write_stats(args)
        else:
            print(f"export_onnx: {args.check_onnx} agrees with "
                  f"{args.checkpoint} on {len(crops)} crops")
        return 0
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)


if __name__ == "__main__":
    sys.exit(main())
