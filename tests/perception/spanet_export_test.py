"""The SPANet export path's refusals, and the C++ generator against the
PyTorch definition. Run by ctest with Debian's python3; the environment
gives BITEWISE_PERCEPTION_BINARY, BITEWISE_SPANET_MODEL (the generated
development model) and BITEWISE_SOURCE_DIR.
"""

import os
import subprocess
import sys
import tempfile
import unittest
import warnings

import torch

SOURCE = os.environ["BITEWISE_SOURCE_DIR"]
BINARY = os.environ["BITEWISE_PERCEPTION_BINARY"]
GENERATED = os.environ["BITEWISE_SPANET_MODEL"]
SCRIPTS = os.path.join(SOURCE, "scripts", "spanet")
sys.path.insert(0, SCRIPTS)
import export_onnx  # noqa: E402
import make_test_checkpoint  # noqa: E402
import spanet_model as sm  # noqa: E402


def run_export(*args):
    return subprocess.run(
        [sys.executable, os.path.join(SCRIPTS, "export_onnx.py"),
         f"--perception_binary={BINARY}", *args],
        capture_output=True, text=True)


class ExportRefusesWhatIsNotSpanet(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory(prefix="spanet-export-test-")
        cls.state = make_test_checkpoint.make(seed=11).state_dict()

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def path(self, name):
        return os.path.join(self.tmp.name, name)

    def export_refused(self, state, name):
        checkpoint = self.path(name + ".pth")
        torch.save({"net": state}, checkpoint)
        out = self.path(name + ".onnx")
        run = run_export(f"--checkpoint={checkpoint}", f"--out={out}")
        self.assertEqual(run.returncode, 1, run.stderr)
        self.assertFalse(os.path.exists(out), "a refused export left a file")
        self.assertEqual([f for f in os.listdir(self.tmp.name)
                          if f.startswith(".spanet-export-")], [])
        return run.stderr

    def test_missing_keys_are_named(self):
        state = dict(self.state)
        del state["final.weight"]
        del state["linear_layers.4.running_var"]
        stderr = self.export_refused(state, "missing")
        self.assertIn("missing keys: linear_layers.4.running_var, "
                      "final.weight", stderr)

    def test_wrong_shapes_are_named(self):
        # SPANet trained without the location one-hot (use_wall=False).
        state = dict(self.state)
        state["linear_layers.0.weight"] = torch.zeros(2048, 9 * 9 * 256)
        stderr = self.export_refused(state, "no_wall")
        self.assertIn("wrong shapes: linear_layers.0.weight: (2048, 20736) "
                      "(SPANet: (2048, 20739))", stderr)

    def test_unknown_keys_are_named(self):
        state = dict(self.state)
        state["head2.weight"] = torch.zeros(3)
        stderr = self.export_refused(state, "unknown")
        self.assertIn("unexpected keys: head2.weight", stderr)

    def test_non_finite_weights_are_refused(self):
        state = dict(self.state)
        state["final.bias"] = torch.full((10,), float("nan"))
        self.assertIn("non-finite values in final.bias",
                      self.export_refused(state, "nan"))

    def test_a_file_that_is_not_a_checkpoint(self):
        path = self.path("garbage.pth")
        with open(path, "w") as f:
            f.write("not a checkpoint")
        run = run_export(f"--checkpoint={path}", f"--out={self.path('g.onnx')}")
        self.assertEqual(run.returncode, 1)
        self.assertIn("cannot be read by torch.load", run.stderr)

    def test_module_prefix_and_pickled_module_load(self):
        # nn.DataParallel's "module." prefix, and a whole pickled module
        # left in training mode: both load, the latter with a note.
        prefixed = {"module." + k: v for k, v in self.state.items()}
        self.assertEqual(set(sm.state_dict_from_checkpoint(prefixed)),
                         set(self.state))
        module = make_test_checkpoint.make(seed=11).train()
        torch.save(module, self.path("module.pth"))
        model, notes = sm.load_checkpoint(self.path("module.pth"))
        self.assertFalse(model.training)
        self.assertTrue(any("training mode" in n for n in notes), notes)

    def test_a_graph_exported_in_training_mode_is_refused_by_the_service(self):
        model = sm.load_spanet(self.state).train()
        path = self.path("train.onnx")
        # Batch 2: PyTorch cannot run BatchNorm1d in training mode on one.
        # (PyTorch warns at length about exactly this mistake.)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            torch.onnx.export(
                export_onnx._Interface(model),
                (torch.rand(2, 3, 144, 144), torch.eye(3)[[0, 1]]), path,
                opset_version=11, training=torch.onnx.TrainingMode.PRESERVE,
                input_names=["rgb", "loc_type"],
                output_names=["scores", "features"])
        export_onnx.materialize_shared_initializers(path)
        checkpoint = self.path("train.pth")
        torch.save({"net": self.state}, checkpoint)
        run = run_export(f"--checkpoint={checkpoint}", f"--check_onnx={path}")
        self.assertEqual(run.returncode, 1, run.stdout)
        self.assertIn("exported with BatchNorm in training mode", run.stderr)


class GeneratorAgreesWithPytorch(unittest.TestCase):
    """The C++ generator's seeded model, its weights read back from the
    ONNX file into the PyTorch definition, gives the numbers the service
    computes from that file: one architecture, written twice."""

    def test_generated_model(self):
        import onnx
        from onnx import numpy_helper
        graph = onnx.load(GENERATED).graph
        state = {t.name: torch.from_numpy(numpy_helper.to_array(t).copy())
                 for t in graph.initializer}
        model = sm.load_spanet(state, require_depth_branch=False)
        crops = sm.synthetic_crops(seed=5, count=8)
        locations = [sm.LOCATIONS[i % 3] for i in range(len(crops))]
        service = sm.run_service(BINARY, GENERATED, crops, locations)
        for crop, location, got in zip(crops, locations, service):
            with self.subTest(size=crop.shape[:2], location=location):
                scores, features = sm.run_pytorch(model, crop, location)
                self.assertTrue((got["canvas"] == sm.canvas_uint8(crop)).all())
                self.assertLess(sm.relative_error(got["context"], features),
                                1e-4)
                self.assertLess(
                    sm.relative_error(got["action_scores"], scores[4:]), 1e-4)
                self.assertLess(sm.relative_error(
                    got["skewer_points"], sm.skewer_points(scores, crop)), 1e-4)


if __name__ == "__main__":
    unittest.main(verbosity=2)
