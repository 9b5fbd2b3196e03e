"""Round 17 (seamspeed): the shortcuts of mosaic:seamlines give what the long way gives.

The fused cost kernel against the image terms weighted and summed in numpy (bit for bit)."""

from __future__ import annotations

import numpy as np
import pytest

from toolbox.mosaic.kernels import image_cost, image_terms


@pytest.mark.parametrize("shape", [(3, 40, 50), (1, 7, 9), (4, 1, 5), (2, 33, 3)])
@pytest.mark.parametrize("workers", [1, 2])
def test_image_cost_is_the_weighted_image_terms_bit_for_bit(shape, workers):
    rng = np.random.default_rng(sum(shape))
    a = rng.uniform(0, 4000, shape).astype("float32")
    b = rng.uniform(0, 4000, shape).astype("float32")
    scale = 1 / 173.3
    for w_diff, base, w_grad in ((1.0, 0.1, 1.0), (0.3, 0.07, 2.5), (0.0, 0.1, 0.0)):
        diff, grad, gdiff = image_terms(a, b, scale, workers=workers)
        expected = diff * w_diff + base + grad * w_grad
        cost, gdiff2 = image_cost(a, b, scale, w_diff, base, w_grad, workers=workers)
        assert cost.tobytes() == expected.tobytes()
        assert gdiff2.tobytes() == gdiff.tobytes()
