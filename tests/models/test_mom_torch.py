"""MoM encoder/decoder: masking, shapes, decoder geometry and its least-squares initialisation."""

import numpy as np
import torch

from models.mom.training.torch_model import (
    DrawAverage,
    MomDecoder,
    MomEncoder,
    initial_decoder_matrix,
)
from tests.models.mom_scene import look_at_camera


def test_unseen_camera_input_is_ignored():
    torch.manual_seed(0)
    encoder = MomEncoder(3, 12, 16, 32)
    est = torch.randn(5, 3, 12, 2)
    mask = torch.tensor([[1.0, 0.0, 1.0]] * 5)
    other = est.clone()
    other[:, 1] = torch.randn(5, 12, 2) * 10
    torch.testing.assert_close(encoder(est, mask), encoder(other, mask))
    assert not torch.allclose(encoder(est, mask), encoder(est, torch.ones(5, 3)))


def test_decoder_is_a_perspective_projection():
    """With a true camera matrix, the decoder reproduces the camera's projection exactly."""
    projection = look_at_camera([0.0, -4.0, 2.4], [0.0, 0.0, 0.9], 640, 480, 70)
    floor_to_image = projection.copy()
    floor_to_image[:, 3] += 0.9 * projection[:, 2]  # body mean point 0.9 m above the floor
    floor_to_image[:, 2] = 0
    decoder = MomDecoder(floor_to_image[None] / floor_to_image[2, 3])
    world = np.array([[0.5, 1.0], [-1.0, 2.0]])
    expected = np.c_[world, np.full(2, 0.9), np.ones(2)] @ projection.T
    expected = expected[:, :2] / expected[:, 2:]
    got = decoder(torch.tensor(world, dtype=torch.float32)).detach().numpy()[:, 0]
    np.testing.assert_allclose(got, expected, rtol=1e-4)


def test_least_squares_init_recovers_the_homography():
    rng = np.random.default_rng(0)
    truth = np.array([[1.2, 0.1, 0.0, 0.3], [0.05, 0.9, 0.0, -0.2], [0.1, 0.05, 0.0, 1.0]])
    world = rng.uniform(-1, 1, (200, 2))
    homogeneous = np.c_[world, np.zeros(200), np.ones(200)] @ truth.T
    pixels = homogeneous[:, :2] / homogeneous[:, 2:]
    fitted = initial_decoder_matrix(world, pixels)
    projected = np.c_[world, np.zeros(200), np.ones(200)] @ fitted.T
    np.testing.assert_allclose(projected[:, :2] / projected[:, 2:], pixels, atol=1e-8)
    # too few pairs falls back to an affine fit that is still finite
    assert np.isfinite(initial_decoder_matrix(world[:4], pixels[:4])).all()
    # collinear floor positions: no homography exists, the affine map is used
    line = np.c_[world[:, 0], 0.5 * world[:, 0]]
    assert np.isfinite(initial_decoder_matrix(line, pixels)).all()


def test_draw_average_is_the_mean_of_per_draw_predictions_in_metres():
    torch.manual_seed(1)
    encoder = MomEncoder(2, 12, 8, 16).eval()
    wrapper = DrawAverage(encoder, np.array([3.0, -1.0]), 2.5)
    est, mask = torch.randn(4, 5, 2, 12, 2), torch.ones(4, 2)
    per_draw = torch.stack([encoder(est[:, d], mask) for d in range(5)], dim=1)
    torch.testing.assert_close(
        wrapper(est, mask), per_draw.mean(dim=1) * 2.5 + torch.tensor([3.0, -1.0])
    )
