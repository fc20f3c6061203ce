"""The losses of METHOD.md, numbered as in the paper (section 3.3).

Tensors are words in channel layout (B, F, T) with F = J*C features (J bones, C values
per bone, i.e. the paper's i) and T frames. Means are over t, j, i as in (1)-(6); the
temporal losses (7)-(10) are SUMS over the T-1 frame pairs, the bones and the values, as
the paper writes them. Over the batch every loss is averaged, so a loss's size does not
depend on the batch size: a batch of one word gives exactly the paper's formula.

Note the scale this implies: with T = 60, J = 22, C = 3 a sum has 3894 terms, which is
why the paper's weights are small (lambda_diff = 0.01, lambda_coherence = 0.001).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from stylecast.motion.clock import OUTPUT_FPS as FPS  # a word's frame rate: velocities below are per second

LAMBDA_CYCLE = 20.0
LAMBDA_DIFF = 0.01
LAMBDA_COHERENCE = 0.001
LAMBDA_GRAM = 0.0  # off unless asked for: the dynamics-style term is an option (seed 004)
LOSS_KINDS = ("cycle-diff", "coherence")


def _per_word_mean(x: torch.Tensor) -> torch.Tensor:
    return x.mean()


def _per_word_sum(x: torch.Tensor) -> torch.Tensor:
    """Sum over every axis but the batch, then the batch mean."""
    return x.reshape(x.shape[0], -1).sum(dim=1).mean()


def diff(x: torch.Tensor) -> torch.Tensor:
    """diff(x)_t = x_t - x_{t-1} over the T-1 frame pairs (time is the last axis)."""
    return x[..., 1:] - x[..., :-1]


# (1), (2): discriminators, least squares
def discriminator_loss(d_real: torch.Tensor, d_fake: torch.Tensor) -> torch.Tensor:
    return 0.5 * _per_word_mean((1.0 - d_real) ** 2) + discriminator_loss_fake(d_fake)


def discriminator_loss_fake(d_fake: torch.Tensor) -> torch.Tensor:
    """The fake half of ``discriminator_loss`` alone."""
    return 0.5 * _per_word_mean(d_fake ** 2)


# (3), (4): generators, least squares
def generator_loss(d_fake: torch.Tensor) -> torch.Tensor:
    return _per_word_mean((1.0 - d_fake) ** 2)


# (5), (6): cycle consistency, L1 mean
def cycle_loss(reconstructed: torch.Tensor, original: torch.Tensor) -> torch.Tensor:
    return _per_word_mean((reconstructed - original).abs())


# (9), (10): the paper's cycle-consistency temporal-difference loss, a sum
def diff_loss(reconstructed: torch.Tensor, original: torch.Tensor) -> torch.Tensor:
    return _per_word_sum((diff(reconstructed) - diff(original)).abs())


# (7), (8): Adult2Child's temporal coherence loss, a sum
def coherence_loss(generated: torch.Tensor) -> torch.Tensor:
    return _per_word_sum(diff(generated).abs())


# Seed 004's dynamics style: Gram matrices of velocity features. A word's Gram matrix
# G = V V^T / (T-1), V the (F, T-1) frame-to-frame velocities, says which bones move
# together and how strongly, regardless of when; matching the batch-mean Gram of generated
# and real words of the target style asks for the target's dynamics without pairing words.
def velocity_gram(x: torch.Tensor) -> torch.Tensor:
    v = diff(x) * FPS
    return v @ v.transpose(1, 2) / v.shape[-1]


def gram_loss(generated: torch.Tensor, real: torch.Tensor) -> torch.Tensor:
    return ((velocity_gram(generated).mean(dim=0) - velocity_gram(real).mean(dim=0)) ** 2).mean()


# Overlap consistency (stylecast's, for the stream): the stream serves the newest frames
# of each word and switches word every hop frames, so two words that overlap must agree
# where they do, or every switch turns the motion (the seam blender and the correction
# low-pass then have to hide it). Words i and i+1 of one take overlap by T - shift frames;
# their outputs there should match. Channels ``skip`` (the Hips) are left out: each word's
# heading is removed at its own centre, so the Hips' features of the two differ by design.
def overlap_loss(generated: torch.Tensor, generated_next: torch.Tensor, shift: int, skip: int) -> torch.Tensor:
    return _per_word_mean((generated[:, skip:, shift:] - generated_next[:, skip:, :-shift]).abs())


@dataclass
class GeneratorLosses:
    adv_a2b: torch.Tensor
    adv_b2a: torch.Tensor
    cycle_a: torch.Tensor
    cycle_b: torch.Tensor
    temporal_a: torch.Tensor  # L_diff,a or L_coherence,a depending on the loss kind
    temporal_b: torch.Tensor
    gram_a2b: torch.Tensor  # dynamics style of the generated B words against real B words
    gram_b2a: torch.Tensor
    total: torch.Tensor


def generator_objective(kind: str, a, b, fake_b, fake_a, rec_a, rec_b, d_b_fake, d_a_fake,
                        lambda_cycle: float = LAMBDA_CYCLE, lambda_diff: float = LAMBDA_DIFF,
                        lambda_coherence: float = LAMBDA_COHERENCE, lambda_gram: float = LAMBDA_GRAM) -> GeneratorLosses:
    """The generators' part of (11): L_Ga2b + L_Gb2a + lambda_cycle (L_cycle,a + L_cycle,b)
    + lambda_diff (L_diff,a + L_diff,b) for "cycle-diff"; the baseline "coherence" swaps
    the last term for lambda_coherence (L_coherence,a + L_coherence,b). Nothing else
    differs between the two. ``lambda_gram`` > 0 adds the dynamics-style term
    lambda_gram (L_gram(G_a2b(a), b) + L_gram(G_b2a(b), a)) to either."""
    if kind not in LOSS_KINDS:
        raise ValueError(f"loss must be one of {LOSS_KINDS}, got {kind!r}")
    adv_a2b = generator_loss(d_b_fake)
    adv_b2a = generator_loss(d_a_fake)
    cyc_a = cycle_loss(rec_a, a)
    cyc_b = cycle_loss(rec_b, b)
    if kind == "cycle-diff":
        t_a, t_b, lam = diff_loss(rec_a, a), diff_loss(rec_b, b), lambda_diff
    else:
        t_a, t_b, lam = coherence_loss(fake_b), coherence_loss(fake_a), lambda_coherence
    total = adv_a2b + adv_b2a + lambda_cycle * (cyc_a + cyc_b) + lam * (t_a + t_b)
    if lambda_gram > 0:
        g_ab, g_ba = gram_loss(fake_b, b), gram_loss(fake_a, a)
        total = total + lambda_gram * (g_ab + g_ba)
    else:  # not computed: reported as zero
        g_ab = g_ba = torch.zeros((), device=total.device)
    return GeneratorLosses(adv_a2b, adv_b2a, cyc_a, cyc_b, t_a, t_b, g_ab, g_ba, total)
