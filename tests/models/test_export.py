"""Export: the ONNX encoder matches PyTorch, model.json is complete and serving-ready."""

import json

import numpy as np
import torch

from models.mom.runtime import MomRuntime
from models.mom.sampling import SamplerConfig
from models.mom.training.export import pixel_decoder
from models.mom.training.torch_model import DrawAverage, MomDecoder, MomEncoder
from tests.models.mom_scene import make_dataset, trained_model


def _torch_model(out):
    checkpoint = torch.load(out / "model.pt", weights_only=True)
    settings = checkpoint["settings"]
    meta = json.loads((out / "model.json").read_text())
    k, rows = meta["num_cameras"], SamplerConfig(**meta["sampler"]).rows
    encoder = MomEncoder(k, rows, settings["camera_width"], settings["global_width"])
    encoder.load_state_dict(checkpoint["encoder"])
    decoder = MomDecoder(np.zeros((k, 3, 4)))
    decoder.load_state_dict(checkpoint["decoder"])
    return (
        DrawAverage(encoder, checkpoint["centre"], checkpoint["scale"]).eval(),
        decoder,
        checkpoint,
    )


def test_onnx_matches_pytorch_on_1000_samples():
    out, _, _ = trained_model()
    runtime = MomRuntime.load(out)
    data, _ = make_dataset(1000, cameras=2, seed=99)
    wrapper, _, _ = _torch_model(out)
    est, mask = runtime.encoder_inputs(data.boxes)
    with torch.no_grad():
        expected = wrapper(torch.from_numpy(est), torch.from_numpy(mask)).numpy()
    got = runtime.encode(data.boxes)  # the encoder alone: localize may blend in the floor prior
    assert got.shape == (data.n, 2) and data.n > 900
    assert np.abs(got - expected).max() < 1e-3  # metres: under 1 mm


def test_pixel_decoder_matches_normalised_decoder():
    out, data, _ = trained_model()
    runtime = MomRuntime.load(out)
    _, decoder, checkpoint = _torch_model(out)
    world = data.world[:50]
    norm = (world - np.asarray(checkpoint["centre"])) / checkpoint["scale"]
    with torch.no_grad():
        pixels_norm = decoder(torch.tensor(norm, dtype=torch.float32)).numpy()
    expected = (pixels_norm + 1) / 2 * data.image_size
    np.testing.assert_allclose(runtime.reproject(world), expected, rtol=1e-4, atol=0.05)


def test_pixel_decoder_transform_algebra():
    matrices = np.array([np.insert(np.eye(3), 2, 0, axis=1)])  # identity in normalised units
    pixel = pixel_decoder(matrices, np.array([1.0, 2.0]), 2.0, np.array([[640, 480]]))[0]
    point = np.array([3.0, 4.0, 0.0, 1.0]) @ pixel.T
    # normalised (1, 1) → pixel corner (640, 480)
    np.testing.assert_allclose(point[:2] / point[2], [640, 480])


def test_model_json_is_complete():
    out, data, _ = trained_model()
    meta = json.loads((out / "model.json").read_text())
    for key in (
        "num_cameras",
        "image_sizes",
        "observation",
        "sampler",
        "draws",
        "normalisation",
        "decoder",
        "metrics",
        "version",
    ):
        assert key in meta
    assert meta["image_sizes"] == data.image_size.tolist()
    assert np.asarray(meta["decoder"]["matrices"]).shape == (2, 3, 4)
    assert len(meta["draws"]["unit"]) == meta["sampler"]["draws"]
