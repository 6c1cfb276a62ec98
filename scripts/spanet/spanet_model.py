"""SPANet's RGB path in PyTorch, and the reference for everything around it.

Written here from the architecture table in docs/perception.md (Feng et al.
2019; the visual model of Gordon et al. 2021). Module and parameter names
follow the public SPANet checkpoints, so that a lab's `.pth` loads with
`load_state_dict(strict=True)`: the depth branch (`conv_init_depth`,
`conv_merge`) exists only so that its keys have a home; the service runs
RGB only.

This module also holds the reference preprocessing (PIL's Lanczos resize
of the crop's longer side to 144, centred paste on black, [0, 1]), the
checkpoint reader with its documented key map, and the runner for the
service's own loader (`bitewise-perception --check_model`). It is imported
by export_onnx.py, check_generator.py and the tests; it has no command line.
"""

import os
import subprocess
import tempfile

import numpy as np
import torch
from PIL import Image
from torch import nn

IMAGE_SIZE = 144
FEATURES = 2048
SCORES = 10  # x0, y0, x1, y1, then VS0, VS90, TV0, TV90, TA0, TA90
LOCATIONS = ("isolated", "wall", "lettuce")
FLATTENED = 9 * 9 * 256


def _conv_bn(in_channels, out_channels, kernel, pool):
    """Conv (same padding), BatchNorm, optional 2x2 max pool, ReLU."""
    layers = [
        nn.Conv2d(in_channels, out_channels, kernel, padding=kernel // 2),
        nn.BatchNorm2d(out_channels),
    ]
    if pool:
        layers.append(nn.MaxPool2d(2))
    layers.append(nn.ReLU())
    return layers


class SPANet(nn.Module):
    """SPANet with use_rgb=True, use_depth=False, use_wall=True.

    forward(rgb [N,3,144,144] in [0,1], loc_type [N,3] one-hot) returns
    (scores [N,10] after the sigmoid, features [N,2048]), the order of the
    public code's forward.
    """

    def __init__(self):
        super().__init__()
        # 144 -> 72, 3 -> 32 channels.
        self.conv_init_rgb = nn.Sequential(
            *_conv_bn(3, 16, 7, pool=False), *_conv_bn(16, 32, 3, pool=True))
        # The depth branch and the merge of the public class: never run
        # here, present so that checkpoints load strictly.
        self.conv_init_depth = nn.Sequential(
            *_conv_bn(1, 16, 11, pool=False), *_conv_bn(16, 32, 3, pool=True))
        self.conv_merge = nn.Sequential(*_conv_bn(64, 32, 3, pool=False))
        # 72 -> 36 -> 18 -> 9, 32 -> 64 -> 128 -> 256 channels.
        self.conv_layers_top = nn.Sequential(
            *_conv_bn(32, 64, 3, pool=True), *_conv_bn(64, 128, 3, pool=True),
            *_conv_bn(128, 256, 3, pool=True))
        # Applied three times with residual adds, weights shared.
        self.conv_layers_bot = nn.Sequential(*_conv_bn(256, 256, 3, pool=False))
        self.linear_layers = nn.Sequential(
            nn.Linear(FLATTENED + 3, FEATURES), nn.BatchNorm1d(FEATURES),
            nn.ReLU(), nn.Linear(FEATURES, FEATURES),
            nn.BatchNorm1d(FEATURES), nn.ReLU())
        self.final = nn.Linear(FEATURES, SCORES)

    def forward(self, rgb, loc_type):
        x = self.conv_layers_top(self.conv_init_rgb(rgb))
        for _ in range(3):
            x = self.conv_layers_bot(x) + x
        x = torch.cat((torch.flatten(x, 1), loc_type), dim=1)
        features = self.linear_layers(x)
        return self.final(features).sigmoid(), features


# Keys of the RGB path: everything but the depth branch and the merge.
def rgb_path_keys(model):
    return [k for k in model.state_dict()
            if not k.startswith(("conv_init_depth.", "conv_merge."))]


class CheckpointError(Exception):
    """A checkpoint that cannot be SPANet's; the message says why."""


def state_dict_from_checkpoint(obj):
    """The state_dict inside what torch.load returned.

    Key map (documented in docs/perception.md): a bare state_dict; a dict
    holding it under "net", "state_dict" or "model_state_dict" (training
    scripts save {"net": ..., "epoch": ...}); a whole pickled nn.Module;
    and a "module." prefix on every key (nn.DataParallel) is removed.
    """
    if isinstance(obj, nn.Module):
        obj = obj.state_dict()
    if isinstance(obj, dict):
        for wrapper in ("net", "state_dict", "model_state_dict"):
            if wrapper in obj and isinstance(obj[wrapper], dict):
                obj = obj[wrapper]
                break
    if not isinstance(obj, dict) or not all(
            isinstance(v, torch.Tensor) for v in obj.values()):
        raise CheckpointError(
            "holds no state_dict (expected tensors by name, or a dict with "
            "\"net\", \"state_dict\" or \"model_state_dict\")")
    if obj and all(k.startswith("module.") for k in obj):
        obj = {k[len("module."):]: v for k, v in obj.items()}
    return obj


def load_spanet(state, require_depth_branch=True):
    """A SPANet in eval mode holding `state`, checked key by key.

    Every RGB-path key must be present with its shape; no unknown key is
    allowed. With require_depth_branch=False the depth branch, the merge
    and BatchNorm's num_batches_tracked may be absent (the generated ONNX
    model has neither). Raises CheckpointError naming the keys.
    """
    model = SPANet()
    expected = model.state_dict()
    optional = set()
    if not require_depth_branch:
        optional = {k for k in expected if k not in rgb_path_keys(model)
                    or k.endswith("num_batches_tracked")}
    missing = [k for k in expected if k not in state and k not in optional]
    unexpected = [k for k in state if k not in expected]
    wrong = [f"{k}: {tuple(state[k].shape)} (SPANet: {tuple(v.shape)})"
             for k, v in expected.items()
             if k in state and tuple(state[k].shape) != tuple(v.shape)]
    problems = []
    if missing:
        problems.append(f"missing keys: {', '.join(missing)}")
    if unexpected:
        problems.append(f"unexpected keys: {', '.join(unexpected)}")
    if wrong:
        problems.append(f"wrong shapes: {'; '.join(wrong)}")
    if problems:
        raise CheckpointError("not SPANet's RGB path (use_rgb, use_wall, "
                              "2048 features): " + "; ".join(problems))
    nonfinite = [k for k, v in state.items()
                 if v.is_floating_point() and not torch.isfinite(v).all()]
    if nonfinite:
        raise CheckpointError(f"non-finite values in {', '.join(nonfinite)}")
    bad_var = [k for k, v in state.items()
               if k.endswith("running_var") and not (v > 0).all()]
    if bad_var:
        raise CheckpointError(
            f"BatchNorm running variances not positive in {', '.join(bad_var)}")
    model.load_state_dict(state, strict=False)
    return model.eval()


def load_checkpoint(path):
    try:
        obj = torch.load(path, map_location="cpu")
    except Exception as e:  # pickle, zip and torch errors alike
        raise CheckpointError(f"cannot be read by torch.load: {e}") from e
    was_training = isinstance(obj, torch.nn.Module) and obj.training
    state = state_dict_from_checkpoint(obj)
    model = load_spanet(state)
    notes = []
    if was_training:
        notes.append("the pickled module was in training mode; exported in "
                     "eval mode (BatchNorm running statistics)")
    untouched = [k for k, v in state.items() if k.endswith("running_var")
                 and k in rgb_path_keys(model)
                 and torch.all(v == 1) and torch.all(
                     state[k.replace("running_var", "running_mean")] == 0)]
    if untouched:
        notes.append("BatchNorm running statistics at their initial values "
                     f"in {', '.join(untouched)}: was this checkpoint saved "
                     "before training?")
    return model, notes


def placement(width, height):
    """(new_width, new_height, left, top) as SPANet's own preprocessing."""
    ratio = float(IMAGE_SIZE / max(width, height))
    new_w, new_h = int(width * ratio), int(height * ratio)
    return new_w, new_h, (IMAGE_SIZE - new_w) // 2, (IMAGE_SIZE - new_h) // 2


def canvas_uint8(crop):
    """The 144x144 RGB uint8 canvas for an HxWx3 uint8 RGB crop (PIL)."""
    image = Image.fromarray(np.ascontiguousarray(crop), "RGB")
    new_w, new_h, left, top = placement(*image.size)
    canvas = Image.new("RGB", (IMAGE_SIZE, IMAGE_SIZE))
    canvas.paste(image.resize((new_w, new_h), Image.LANCZOS), (left, top))
    return np.asarray(canvas)


def to_tensor(canvas):
    """uint8 HxWx3 -> float [1,3,H,W] in [0,1] (torchvision's ToTensor)."""
    t = torch.from_numpy(np.array(canvas, dtype=np.uint8)).permute(2, 0, 1)
    return t.float().div(255).unsqueeze(0)


def one_hot(location):
    loc = torch.zeros(1, 3)
    loc[0, LOCATIONS.index(location)] = 1.0
    return loc


@torch.no_grad()
def run_pytorch(model, crop, location):
    """(scores [10], features [2048]) as float64 numpy arrays (eval mode:
    BatchNorm from running statistics)."""
    assert not model.training, "the reference runs SPANet in eval mode"
    scores, features = model(to_tensor(canvas_uint8(crop)), one_hot(location))
    return scores[0].double().numpy(), features[0].double().numpy()


def skewer_points(scores, crop):
    """The head's canvas points in crop-normalised coordinates, as
    Featurize reports them."""
    height, width = crop.shape[:2]
    new_w, new_h, left, top = placement(width, height)
    out = []
    for i in range(2):
        out += [(scores[2 * i] * IMAGE_SIZE - left) / new_w,
                (scores[2 * i + 1] * IMAGE_SIZE - top) / new_h]
    return np.array(out)


def synthetic_crops(seed=3, count=6):
    """Crops with structure at several scales, of odd and even sizes,
    portrait and landscape, shrunk and enlarged (deterministic)."""
    rng = np.random.default_rng(seed)
    sizes = [(57, 203), (200, 100), (143, 145), (31, 18), (96, 96),
             (301, 77), (64, 151), (145, 144)]
    crops = []
    for height, width in sizes[:count]:
        yy, xx = np.mgrid[0:height, 0:width]
        base = np.stack([np.sin(xx / (3 + c) + c) * np.cos(yy / (5 + 2 * c))
                         for c in range(3)], axis=-1)
        noise = rng.normal(0, 0.25, (height, width, 3))
        crops.append(np.clip(127.5 + 110 * (base + noise), 0, 255)
                     .astype(np.uint8))
    return crops


def save_png(path, rgb):
    Image.fromarray(np.ascontiguousarray(rgb), "RGB").save(path)


def load_png(path):
    return np.asarray(Image.open(path).convert("RGB"))


class ServiceCheckError(Exception):
    """The service's loader refused the model, or its output is unreadable."""


def run_service(binary, model_path, crops, locations):
    """Featurizes crops through `bitewise-perception --check_model`.

    Returns a list of dicts with "canvas" (uint8 144x144x3), "scores" [10]
    and "features" [2048], one per crop, in order.
    """
    with tempfile.TemporaryDirectory(prefix="spanet-check-") as tmp:
        specs = []
        for i, (crop, location) in enumerate(zip(crops, locations)):
            path = os.path.join(tmp, f"crop{i}.png")
            save_png(path, crop)
            specs.append(f"{path}:{location}")
        out_dir = os.path.join(tmp, "out")
        os.mkdir(out_dir)
        cmd = [binary, "--featurizer=spanet", f"--spanet_model={model_path}",
               "--check_model", f"--check_crops={','.join(specs)}",
               f"--check_out={out_dir}"]
        run = subprocess.run(cmd, capture_output=True, text=True)
        if run.returncode != 0:
            raise ServiceCheckError(
                f"{os.path.basename(binary)} --check_model refused "
                f"{model_path} (exit {run.returncode}): "
                f"{run.stderr.strip()}")
        results = []
        for i in range(len(crops)):
            values = {}
            with open(os.path.join(out_dir, f"crop{i}.txt")) as f:
                for line in f:
                    name, *numbers = line.split()
                    values[name] = np.array([float(v) for v in numbers])
            values["canvas"] = load_png(
                os.path.join(out_dir, f"crop{i}.canvas.png"))
            results.append(values)
        return results


def relative_error(got, want):
    """max |got - want| / max(max |want|, tiny): one number per vector."""
    scale = max(float(np.max(np.abs(want))), 1e-12)
    return float(np.max(np.abs(got - want))) / scale
