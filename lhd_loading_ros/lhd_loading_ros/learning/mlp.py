"""Fully connected ReLU networks with hand-written backward passes and Adam on one flat buffer.

Why not ``nn.Sequential`` + autograd: at the sizes DDPG needs here (12 -> 64 -> 64 -> 3, the config's hidden sizes, or the paper-scale 256 x 256, at
batch 256) a step of PyTorch's eager autograd and ``torch.optim.Adam`` on this 2-core CPU
costs milliseconds of per-operator overhead, more than the arithmetic. One DDPG update
through these classes is a few dozen ``addmm``/elementwise calls plus a six-call Adam on a
single flat parameter vector, and the soft target update is one ``lerp_``. The arithmetic is
exactly that of the layers it replaces (``test_learning.py`` checks gradients and Adam steps
against autograd and ``torch.optim.Adam``).

Layout of the flat vector: for each layer, W (out x in, row-major) then b (out), like
``nn.Linear``; :meth:`FlatMlp.to_sequential` builds the equivalent ``nn.Sequential``.
"""
from __future__ import annotations

import math

import torch

OUT_ACTIVATIONS = ("tanh", "identity")


class FlatMlp:
    """y = out_act(W_n relu(... relu(W_1 x + b_1) ...) + b_n)."""

    def __init__(self, sizes: list[int], out_act: str = "identity", final_init: float | None = 3e-3,
                 generator: torch.Generator | None = None):
        if out_act not in OUT_ACTIVATIONS:
            raise ValueError(f"out_act must be one of {OUT_ACTIVATIONS}, got {out_act!r}")
        if len(sizes) < 2 or any(int(s) < 1 for s in sizes):
            raise ValueError(f"sizes must list at least an input and an output width >= 1, got {sizes}")
        self.sizes = [int(s) for s in sizes]
        self.out_act = out_act
        n = sum(o * i + o for i, o in zip(self.sizes[:-1], self.sizes[1:]))
        self.flat = torch.empty(n, dtype=torch.float32)
        self.grad = torch.zeros(n, dtype=torch.float32)
        self.W, self.b, self.gW, self.gb = self._views(self.flat) + self._views(self.grad)
        self.init(final_init, generator)

    def _views(self, buf: torch.Tensor):
        W, b, k = [], [], 0
        for i, o in zip(self.sizes[:-1], self.sizes[1:]):
            W.append(buf[k:k + o * i].view(o, i))
            k += o * i
            b.append(buf[k:k + o])
            k += o
        return W, b

    def init(self, final_init: float | None, generator: torch.Generator | None = None) -> None:
        """nn.Linear's default init (uniform +-1/sqrt(fan_in)); the last layer uniform
        +-final_init as in Lillicrap et al. (2015), so initial outputs are near zero."""
        with torch.no_grad():
            last = len(self.W) - 1
            for j, (W, b) in enumerate(zip(self.W, self.b)):
                bound = 1.0 / math.sqrt(W.shape[1])
                if j == last and final_init is not None:
                    bound = final_init
                W.uniform_(-bound, bound, generator=generator)
                b.uniform_(-bound, bound, generator=generator)

    @property
    def n_params(self) -> int:
        return self.flat.numel()

    # ------------------------------------------------------------------ forward / backward
    def forward(self, x: torch.Tensor):
        """Return (y, cache); cache holds what backward needs (layer inputs, output)."""
        hs = [x]
        h = x
        last = len(self.W) - 1
        for j, (W, b) in enumerate(zip(self.W, self.b)):
            z = torch.addmm(b, h, W.t())
            if j < last:
                h = z.relu_()
            else:
                h = z.tanh_() if self.out_act == "tanh" else z
            hs.append(h)
        return h, hs

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        return self.forward(x)[0]

    def out_preactivation(self, cache) -> torch.Tensor:
        """z = W_n h_{n-1} + b_n, the output layer's input to out_act, recomputed from a forward's
        cache (forward applies tanh in place; one B x hidden x out product)."""
        return torch.addmm(self.b[-1], cache[-2], self.W[-1].t())

    def backward(self, cache, dy: torch.Tensor, weight_grads: bool = True, input_grad: bool = False,
                 dz_out: torch.Tensor | None = None):
        """Back-propagate dL/dy. weight_grads: write dL/dtheta into self.grad (overwriting);
        input_grad: return dL/dx. Neither changes the parameters. dz_out: a gradient on the output
        layer's pre-activation z itself (a loss on z, such as a penalty on tanh's input), added after
        out_act's derivative, where a saturated tanh would have scaled it away."""
        hs = cache
        last = len(self.W) - 1
        y = hs[-1]
        dz = dy * (1.0 - y * y) if self.out_act == "tanh" else dy
        if dz_out is not None:
            dz = dz + dz_out
        dx = None
        for j in range(last, -1, -1):
            h_in = hs[j]
            if weight_grads:
                torch.mm(dz.t(), h_in, out=self.gW[j])
                torch.sum(dz, 0, out=self.gb[j])
            if j > 0 or input_grad:
                dh = dz.mm(self.W[j])
                if j > 0:
                    # relu'(z) = 1 where the layer's output is positive: dh where h_in > 0, else 0. One
                    # fused kernel; dh.mul_(h_in > 0) gives the same values at 8 times the cost (the
                    # bool mask's conversion to float was a third of a DDPG update)
                    dz = torch.ops.aten.threshold_backward(dh, h_in, 0.0)
                else:
                    dx = dh
        return dx

    # ------------------------------------------------------------------ helpers
    def copy_from(self, other: "FlatMlp") -> None:
        if other.sizes != self.sizes:
            raise ValueError(f"network sizes differ: {self.sizes} vs {other.sizes}")
        self.flat.copy_(other.flat)

    def soft_update_from(self, other: "FlatMlp", tau: float) -> None:
        """theta_target <- tau theta + (1 - tau) theta_target."""
        self.flat.lerp_(other.flat, tau)

    def to_sequential(self) -> torch.nn.Sequential:
        layers: list[torch.nn.Module] = []
        for j, (W, b) in enumerate(zip(self.W, self.b)):
            lin = torch.nn.Linear(W.shape[1], W.shape[0])
            with torch.no_grad():
                lin.weight.copy_(W)
                lin.bias.copy_(b)
            layers.append(lin)
            if j < len(self.W) - 1:
                layers.append(torch.nn.ReLU())
            elif self.out_act == "tanh":
                layers.append(torch.nn.Tanh())
        return torch.nn.Sequential(*layers)

    def numpy_weights(self) -> list[tuple]:
        return [(W.detach().numpy().copy(), b.detach().numpy().copy()) for W, b in zip(self.W, self.b)]


class FlatAdam:
    """Adam (Kingma & Ba) over a FlatMlp's flat parameter and gradient buffers; the same
    arithmetic as torch.optim.Adam (no weight decay, no amsgrad)."""

    def __init__(self, net: FlatMlp, lr: float, betas=(0.9, 0.999), eps: float = 1e-8):
        if not lr > 0:
            raise ValueError(f"learning rate must be > 0, got {lr}")
        self.net = net
        self.lr, (self.b1, self.b2), self.eps = float(lr), betas, float(eps)
        self.m = torch.zeros_like(net.flat)
        self.v = torch.zeros_like(net.flat)
        self.t = 0
        self._denom = torch.empty_like(net.flat)

    def step(self) -> None:
        self.t += 1
        g = self.net.grad
        self.m.lerp_(g, 1.0 - self.b1)
        self.v.mul_(self.b2).addcmul_(g, g, value=1.0 - self.b2)
        bc1 = 1.0 - self.b1 ** self.t
        bc2 = 1.0 - self.b2 ** self.t
        torch.sqrt(self.v, out=self._denom)
        self._denom.div_(math.sqrt(bc2)).add_(self.eps)
        self.net.flat.addcdiv_(self.m, self._denom, value=-self.lr / bc1)

    def state_dict(self) -> dict:
        return {"m": self.m.clone(), "v": self.v.clone(), "t": self.t}

    def load_state_dict(self, d: dict) -> None:
        self.m.copy_(d["m"])
        self.v.copy_(d["v"])
        self.t = int(d["t"])
