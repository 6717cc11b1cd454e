"""A PyTorch adapter: the renderer as a differentiable function of scene parameters.

    import torch, difftransient as dt
    from difftransient.torch import render
    scene = dt.Scene.load("scenes/pose_plate.toml")
    theta = torch.tensor([0.1, 20.0], requires_grad=True)
    image = render(scene, ["plate_x", "plate_roll"], theta, spp=16)   # [H, W, T, C] tensor
    loss = ((image - target) ** 2).sum()
    loss.backward()                                                  # theta.grad

The forward pass renders the scene with the parameter values of `theta`; the backward pass
runs the adjoint (`difftransient.gradient`) with ∂loss/∂image on samples of its own (seed
`seed + 1`, as in the optimizer of `dtr optimize`), so the gradient is independent of the
forward noise. With no seed, every call draws a fresh one, so that an optimiser's iterations
see new noise each time (with one frozen set of samples it would settle where that noise
puts it); a seed fixes the samples of every call (for finite differences with common random
numbers).
"""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np
import torch

from . import Scene, _draw_seed, gradient
from . import render as _render

__all__ = ["render", "RenderFunction"]


class RenderFunction(torch.autograd.Function):
    """forward(theta, scene, names, options, estimators) → transient; backward → dL/dθ by the
    adjoint with those estimators."""

    @staticmethod
    def forward(ctx, theta: torch.Tensor, scene: Scene, names: Sequence[str], options: dict,
                estimators: str = "full"):
        values = {n: float(v) for n, v in zip(names, theta.detach().cpu().tolist())}
        at = scene.with_params(values)
        options = dict(options, seed=_draw_seed(options.get("seed")))
        r = _render(at, **options)
        ctx.scene, ctx.names, ctx.options, ctx.estimators = at, list(names), options, estimators
        ctx.theta_dtype, ctx.theta_device = theta.dtype, theta.device
        return torch.from_numpy(r.transient).to(theta.device)

    @staticmethod
    def backward(ctx, grad_output: torch.Tensor):
        options = dict(ctx.options, estimators=ctx.estimators)
        options["seed"] += 1
        adj = grad_output.detach().to("cpu", torch.float32).contiguous().numpy()
        g, _ = gradient(ctx.scene, ctx.names, adj, **options)
        grad = torch.from_numpy(np.asarray(g)).to(ctx.theta_dtype).to(ctx.theta_device)
        return grad, None, None, None, None


def render(scene: Scene, names: Sequence[str], theta: torch.Tensor, *, spp: Optional[int] = None,
           seed: Optional[int] = None, threads: Optional[int] = None, estimators: str = "full") -> torch.Tensor:
    """The transient [H, W, T, C] of `scene` with parameters `names` set to `theta` (1-D),
    differentiable with respect to `theta`. `estimators` is the backward pass's choice of
    gradient terms, as in `difftransient.gradient` ("interior" for a smooth dielectric's index,
    whose boundary term is refused)."""
    if theta.dim() != 1 or theta.numel() != len(names):
        raise ValueError(f"theta must be 1-D with one value per name ({len(names)}), got shape {tuple(theta.shape)}")
    options = {"spp": spp, "seed": seed, "threads": threads}
    return RenderFunction.apply(theta, scene, list(names), options, estimators)
