"""stylecast.models: the CycleGAN restyler of the source paper (cycle-consistency
temporal-difference loss): representation, networks, losses, data, training, checkpoints,
offline restyling and evaluation. Torch is imported only where networks run.

    from stylecast.models import Restyler
    r = Restyler.load()            # models/checkpoints/normal2exhausted, normal -> exhausted
    out = r.restyle_words(words)   # (B, 60, 22, 4) humanoid local quaternions xyzw
"""

from .restyler import MODEL_KINDS, Restyler
from .restyler_multistyle import MultiStyleRestyler  # registers the kind "multistyle"

__all__ = ["MODEL_KINDS", "MultiStyleRestyler", "Restyler"]
