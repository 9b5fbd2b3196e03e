"""Round 17: the bundle's redundancy when data snooping takes a control point's last ray."""

import numpy as np

import toolbox.triangulation.adjust as adjust_module
from toolbox.triangulation.approximations import by_resection
from toolbox.triangulation.block import Options
from toolbox.triangulation.inputs import BlockRequest, Control, Measurements, build_block
from toolbox.triangulation.solver import KIND_IMAGE
from toolbox.triangulation.synthetic import SyntheticBlockSpec, corner_control, make_block


def _solve(sb, keep, control_idx, lonely_id=None):
    """The block of observations ``keep`` and full control ``control_idx``, adjusted; snooping
    rejects the ray of point ``lonely_id`` first (as if its w-test were the largest), then
    nothing: the rejection's own bookkeeping is the toolbox's."""
    ids = [sb.point_ids[i] for i in control_idx]
    control = Control(ids, sb.points[control_idx], ["control"] * len(ids))
    ms = Measurements([sb.obs_point[k] for k in keep], [sb.obs_photo[k] for k in keep],
                      np.asarray(sb.xy)[keep], sb.kind, np.full(len(keep), np.nan))
    block, _ = build_block(BlockRequest(sb.project, ms, control, sigma_mm=sb.sigma,
                                        sigma_px=sb.sigma, control_sigma_xy=0.01,
                                        control_sigma_z=0.01))
    real = adjust_module._reject
    calls = []

    def reject_the_lonely_ray_first(problem, lin, w, r, options):
        calls.append(1)
        if lonely_id is None or len(calls) > 1:
            return None
        point = block.point_ids.index(lonely_id)
        rows = (lin.kind == KIND_IMAGE) & (block.obs_point[lin.index] == point)
        return real(problem, lin, np.where(rows, 100.0, 0.0), r, options)

    adjust_module._reject = reject_the_lonely_ray_first
    try:
        ext0, pts0, _ = by_resection(block)
        return block, adjust_module.adjust(block, ext0, pts0, Options())
    finally:
        adjust_module._reject = real


def test_a_control_point_whose_last_ray_is_rejected_adds_no_redundancy():
    """A full control point seen on one photo whose ray snooping rejects is held by its three
    ground rows alone: three rows, three unknowns, no redundancy. The redundancy and sigma0 are
    those of the block without that point (it counted the rows but not the unknowns: +3)."""
    sb = make_block(SyntheticBlockSpec(digital=True, seed=1))
    chosen = corner_control(sb, 7)
    control, lonely = chosen[:6], chosen[6]
    lonely_id = sb.point_ids[lonely]
    rays = [k for k, p in enumerate(sb.obs_point) if p == lonely_id]
    others = [k for k, p in enumerate(sb.obs_point) if p != lonely_id]
    block, rejected = _solve(sb, sorted(others + rays[:1]), control + [lonely], lonely_id)
    assert [r.kind for r in rejected.rejections] == ["image"]
    assert block.point_ids[block.obs_point[rejected.rejections[0].index]] == lonely_id
    _, without = _solve(sb, others, control)
    assert rejected.redundancy == without.redundancy
    assert abs(rejected.sigma0 - without.sigma0) < 1e-6 * without.sigma0
