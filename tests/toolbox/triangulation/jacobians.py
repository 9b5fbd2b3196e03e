"""A central-difference check of the analytic Jacobians of the collinearity residuals."""

from collections.abc import Callable

import numpy as np


def assert_central_differences(residuals: Callable, args: list, which: int, steps: list,
                               atol: float) -> None:
    """``residuals(*args)[which]`` (the Jacobian of the residuals with respect to ``args[which -
    1]``, shape (m, 2, k)) equals central differences of ``residuals(*args, jacobians=False)[0]``
    with the step ``steps[k]`` on each column, within 1e-6 of the largest entry + ``atol``."""
    jac = residuals(*args)[which]
    arr = args[which - 1]
    for k, h in enumerate(steps):
        plus, minus = arr.copy(), arr.copy()
        plus[:, k] += h
        minus[:, k] -= h
        a1, a2 = list(args), list(args)
        a1[which - 1], a2[which - 1] = plus, minus
        num = (residuals(*a1, jacobians=False)[0] - residuals(*a2, jacobians=False)[0]) / (2 * h)
        assert np.abs(num - jac[:, :, k]).max() <= 1e-6 * np.abs(jac[:, :, k]).max() + atol
