"""An exponential moving average of the generator's weights (``train --ema DECAY``).

GAN generators do not settle: with a constant learning rate the weights keep circling the
equilibrium, and where a run stops on that circle is luck (four seeds of the pair recipe
read 77-91 % judged exhausted). Averaging the weights along the way (Yazici et al., "The
Unusual Effectiveness of Averaging in GAN Training", ICLR 2019) ships the centre of that
circle instead. Training itself is untouched: the average is a shadow copy, updated after
each generator step, that nothing reads until the model is written. So a run with
``--ema`` produces exactly the weights of the same run without it (``model-raw``) and their
average (``model``), which is a clean ablation.

The decay ramps up from 0 as in TensorFlow's ExponentialMovingAverage (``min(decay,
(1 + n) / (10 + n))`` after n updates), so the first steps' near-identity weights do not
linger in the average.
"""

from __future__ import annotations


class WeightAverage:
    """The running average of the tensors of ``module.state_dict()`` whose names start with
    one of ``prefixes`` (the generators). Integer buffers are copied, not averaged."""

    def __init__(self, module, prefixes: tuple[str, ...], decay: float):
        if not 0.0 < decay < 1.0:
            raise ValueError(f"the averaging decay must be between 0 and 1, got {decay:g}")
        self.decay = decay
        self.updates = 0
        self.shadow = {k: v.detach().clone() for k, v in module.state_dict().items() if k.startswith(prefixes)}
        if not self.shadow:
            raise ValueError(f"no weights named {', '.join(prefixes)}* to average")

    def rate(self) -> float:
        """The decay used by the next update (ramped up over the first updates)."""
        return min(self.decay, (1.0 + self.updates) / (10.0 + self.updates))

    def update(self, module) -> None:
        import torch

        keep = self.rate()
        state = module.state_dict()
        with torch.no_grad():
            for name, avg in self.shadow.items():
                now = state[name]
                if avg.is_floating_point():
                    avg.lerp_(now.detach(), 1.0 - keep)
                else:
                    avg.copy_(now)
        self.updates += 1

    def tensors(self, prefix: str = "") -> dict:
        """The averaged tensors, named as in the module (with ``prefix`` put in front)."""
        return {prefix + k: v for k, v in self.shadow.items()}

    def load(self, tensors: dict, updates: int, prefix: str = "") -> None:
        """Restore a saved average (``tensors`` named as ``self.tensors(prefix)`` wrote them)."""
        import torch

        missing = [k for k in self.shadow if prefix + k not in tensors]
        if missing:
            raise ValueError(f"the saved weight average lacks {missing[0]}")
        for name, avg in self.shadow.items():
            avg.copy_(torch.as_tensor(tensors[prefix + name]).reshape(avg.shape))
        self.updates = int(updates)

    def describe(self) -> str:
        return f"exponential moving average of the generator weights over training (decay {self.decay:g}, " \
               f"{self.updates} updates)"
