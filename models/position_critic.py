"""Discriminators over world joint positions (``train --lambda-position-adv``): a second
adversarial term, beside the paper's discriminators over the generator's channels.

Why: the paper's discriminators see joint rotations (Euler angles in the representation),
where every bone weighs the same; what a viewer sees, and what the evaluation's judges read
(``judges.judge_windows``), is joints in space, where a small turn of the spine moves the
head and both hands. Two earlier attempts to make the generator answer to that view used
frozen classifiers (``content.py``): the style loss on rotations was satisfied within two
epochs while the judges read no more exhaustion, and the action loss on positions made the
runs steadier but not stronger (MODEL_CARD.md). A discriminator keeps learning while the
generator does, so it cannot be satisfied by a fixed trick the way a frozen classifier is.

What it is: for each style, the paper's patch discriminator (``networks.Discriminator``:
LSGAN, positions and their per-frame differences) over the joints' positions by forward
kinematics in torch (``content.PositionView``: metres, relative to the hips, heading removed
as in every word), real words against restyled ones. Its weights are drawn from their own
seed (``CRITIC_SALT``), so a run with the term has the same generators, discriminators and
batches at the start as the same seed without it.

Measured (MODEL_CARD.md, "Discriminators over joint positions"): over four draws it lifts
what most judges read by a few points but not the strictest judge, costs action and timing,
and doubles an epoch; so it is off by default."""

from __future__ import annotations

from dataclasses import replace

import torch
from torch import nn

from . import losses as L
from .content import PositionView
from .networks import Discriminator, NetworkConfig

CRITIC_SALT = 104729  # the critics' weights come from (seed + salt), away from the GAN's stream
PREFIX = "critics."  # their tensors in checkpoint.safetensors (for --resume; never in a model file)


class PositionCritics(nn.Module):
    """``D_a`` and ``D_b`` over the positions of style A's and style B's words."""

    def __init__(self, network: NetworkConfig, representation, skeleton, device, seed: int):
        super().__init__()
        self.view = PositionView(representation, skeleton, device)
        positions = replace(network, channels=3)  # x, y, z of each joint
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed + CRITIC_SALT)
            self.D_a = Discriminator(positions)
            self.D_b = Discriminator(positions)
        self.to(device)

    def positions(self, words: torch.Tensor, chunk: int = 512) -> torch.Tensor:
        """Joint positions (N, J*3, T) of channel words (N, J*C, T), without a graph: the
        real words' are computed once for the run (forward kinematics is most of this
        term's cost, 13 ms a batch of 32 forward and 56 with its backward, one thread)."""
        with torch.no_grad():
            return torch.cat([self.view(words[i:i + chunk].to(self.view.offsets.device))
                              for i in range(0, len(words), chunk)])

    def generator_losses(self, fake_b: torch.Tensor, fake_a: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """What G_a2b and G_b2a pay (their restyled channel words judged real by the critic
        of their target style), and the restyled words' positions for ``loss``."""
        positions_b, positions_a = self.view(fake_b), self.view(fake_a)
        return (L.generator_loss(self.D_b(positions_b)), L.generator_loss(self.D_a(positions_a)),
                positions_b, positions_a)

    def loss(self, real_a, real_b, fake_a, fake_b) -> torch.Tensor:
        """The critics' own LSGAN loss on real and restyled positions (the restyled ones
        detached: this step trains the critics only)."""
        return (L.discriminator_loss(self.D_a(real_a), self.D_a(fake_a.detach()))
                + L.discriminator_loss(self.D_b(real_b), self.D_b(fake_b.detach())))
