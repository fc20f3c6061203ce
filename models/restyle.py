"""Offline restyling of a BVH clip (``stylecast restyle``).

read -> ``Retarget.for_clip`` -> humanoid -> resample to 60 fps -> the shared window-and-
blend stream code (``stylecast.motion.words.restyle_stream``, the same cutter and seam
blender the daemon runs live) -> back to the output frame rate -> ``Retarget.to_source``
with the original clip as template -> written with the input's skeleton and joint names.
The root trajectory is the input's but for what the foot lock sets (``motion.footlock``):
the pelvis height (the restyled legs' bend stands on the planted feet) and, with
``--pace style``, the style's pace over the ground.

The live stream starts in pass-through and fades the restyled output in once the first
word is due; an offline clip has no "before", so it is padded at the start (and the end)
by mirroring its own motion. Every real frame is then served by a complete word at full
intensity, and a clip shorter than one word is still restyled.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from stylecast.motion import rotations as rot
from stylecast.motion.clock import OUTPUT_FPS as FPS  # the one definition of the frame rate
from stylecast.motion.errors import UserError
from stylecast.motion.words import DEFAULT_HOP, WORD_LENGTH, Restyled, stream_settings_of


def mirror_indices(num_frames: int, before: int, after: int) -> np.ndarray:
    """Frame indices that extend [0, T) by reflection at both ends (any pad length)."""
    return np.pad(np.arange(num_frames), (before, after), mode="reflect")


CROSSFADE_FRAMES = 30


def padding(hop: int, crossfade_frames: int = CROSSFADE_FRAMES, decay_frames: float | None = None) -> tuple[int, int]:
    """Mirrored frames added (before, after) a clip. Before the first real frame: one word,
    so the words that serve real frames hold no held-pose lead-in of the stream's start
    (``words.first_word_end``), then long enough for the seam spring to settle from
    the stream's first switches (critically damped: (1 + k/d) e^(-k/d) < 0.3 % after
    k = 8 d frames) and, with room to spare, the fade-in (over by then). After the last
    real frame: one hop, so a word covers it with real motion rather than a held pose."""
    from stylecast.motion.words import BlendSettings

    decay = max(BlendSettings(hop=hop).decay_frames, decay_frames or 0.0)  # one grid for blend on and off
    return WORD_LENGTH + max(crossfade_frames, int(np.ceil(8 * decay))), hop


def word_switches(num_frames: int, hop: int, crossfade_frames: int = CROSSFADE_FRAMES,
                  decay_frames: float | None = None) -> np.ndarray:
    """Boolean (T-1,): True where frames t-1 and t of a restyled clip come from different
    words (the seams the paper's section 4.5 is about)."""
    from stylecast.motion.words import serving_word_end

    before, _ = padding(hop, crossfade_frames, decay_frames)
    serving = serving_word_end(np.arange(num_frames) + before, hop)
    return serving[1:] != serving[:-1]


def restyle_rotations(rotations: np.ndarray, restyle_words, hop: int = DEFAULT_HOP, intensity: float = 1.0,
                      crossfade_frames: int = CROSSFADE_FRAMES, decay_frames: float | None = None,
                      live: bool = False, roots: np.ndarray | None = None, skeleton=None,
                      correction_tau: float | None = None, contacts=None,
                      start_restyled: bool = True, held_first: int = 0) -> Restyled:
    """Humanoid rotations (T, J, 4) at 60 fps -> restyled rotations (T, J, 4) and, where
    ``roots`` (T, 3) are given, root positions; any T >= 1.
    ``decay_frames=0`` turns the seam blend off (plain concatenated words). ``live``: no
    mirrored padding, so the result is frame for frame what the daemon sends for the same
    motion (its first words hold the first frame before it). With the root
    positions ``roots`` (T, 3) and the humanoid ``skeleton`` the planted feet are locked
    and the pelvis height set (``motion.footlock``, with ``contacts``, its
    ``ContactSettings``, or the defaults the daemon runs), as the daemon does; without them
    they are not. ``start_restyled``: a live stream's first frame shown restyled, not faded
    in (``BlendSettings.start_restyled``; the model's own is ``words.start_of``).
    ``held_first`` (live only): copies of the first frame the stream starts with, as the
    daemon starts a half-rate source (``half_rate_held``); their frames are not returned."""
    from stylecast.motion.footlock import ContactSettings, FootLock
    from stylecast.motion.words import BlendSettings, restyle_stream

    if not 1 <= hop <= WORD_LENGTH:
        raise UserError(f"--hop must be between 1 and {WORD_LENGTH} frames, got {hop}")
    T = len(rotations)
    settings = BlendSettings(hop=hop, crossfade_frames=crossfade_frames, decay_frames=decay_frames,
                             start_restyled=start_restyled,
                             **({} if correction_tau is None else {"correction_tau": correction_tau}))
    before, after = (0, 0) if live else padding(hop, settings.crossfade_frames, settings.decay_frames)
    if held_first and not live:
        raise ValueError("held_first is the daemon's start of a live stream: only with live=True")
    idx = np.concatenate([np.zeros(held_first, int), mirror_indices(T, before, after)])
    padded = rot.canonical_hemisphere(np.asarray(rotations, dtype=np.float64)[idx])
    feet = None
    if roots is not None:
        roots = np.asarray(roots, dtype=np.float64)[idx]
        if skeleton is not None:
            # The stance (``--feet stance``) of a stream that has been running was taken
            # before the clip began: it follows the lead-in and settles on the first real frame.
            feet = FootLock.for_stream(skeleton, settings.delay, contacts or ContactSettings(),
                                       fade_in=settings.first_fade_end, fade_tau=settings.correction_tau,
                                       lead_in=before, aim=intensity)
    out = restyle_stream(padded, restyle_words, settings, intensity=intensity, roots=roots, feet=feet,
                         first=held_first)
    real = slice(before, before + T)
    moved = None if out.roots is None else out.roots[real].copy()
    if moved is not None and before:
        # The mirrored lead-in walked out and back; whatever horizontal lag a style's pace
        # (``footlock.Pace``) left at the first real frame is taken off, so the clip starts
        # where its input does.
        moved[:, [0, 2]] += roots[before, [0, 2]] - moved[0, [0, 2]]
    return Restyled(out.rotations[real], moved)


def half_rate_held(fps: float, hop: int) -> int:
    """The held copies of its first frame the daemon starts a lone performer's stream of a
    source at ``fps`` with (``words.half_rate_shift``; phase 0, the first group's)."""
    from stylecast.motion.words import half_rate_shift

    shift = half_rate_shift(hop) if abs(2 * fps - FPS) < 1e-9 else None
    return shift or 0


def sample_at(rotations: np.ndarray, fps: float, times: np.ndarray) -> np.ndarray:
    """Slerp a (T, J, 4) sequence at ``fps`` at the given times (seconds), clamped."""
    pos = np.clip(np.asarray(times, dtype=np.float64) * fps, 0.0, len(rotations) - 1)
    lo = np.floor(pos + 1e-9).astype(int)
    lo = np.minimum(lo, len(rotations) - 1)
    hi = np.minimum(lo + 1, len(rotations) - 1)
    frac = np.clip(pos - lo, 0.0, 1.0)
    J = rotations.shape[1]
    q0 = rotations[lo]
    q1 = rotations[hi]
    q1 = np.where(np.sum(q0 * q1, axis=-1, keepdims=True) < 0, -q1, q1)
    return rot.slerp(q0, q1, np.repeat(frac[:, None], J, axis=1))


def restyle_clip(clip, restyler, hop: int = DEFAULT_HOP, intensity: float = 1.0, fps: float | None = None,
                 user_map: dict | None = None, live: bool = False, contacts=None):
    """A source clip -> the restyled clip on the same skeleton (at ``fps`` or the input's);
    ``contacts``: the foot lock's ``ContactSettings`` (default: ``--feet input``'s)."""
    from stylecast.motion.humanoid import Retarget
    from stylecast.motion.resample import resample

    retarget = Retarget.for_clip(clip, user_map)
    humanoid = retarget.to_humanoid(clip)
    h60 = resample(humanoid, FPS)
    restyled60 = restyle_rotations(h60.rotations, restyler.restyle_words, hop, intensity, live=live,
                                   roots=h60.root_positions, skeleton=h60.skeleton, contacts=contacts,
                                   **stream_settings_of(restyler),
                                   held_first=half_rate_held(clip.fps, hop) if live else 0)
    out_fps = float(fps) if fps else clip.fps
    if abs(out_fps - clip.fps) < 1e-9:
        template, h_template = clip, humanoid
    else:
        template = resample(clip, out_fps)
        h_template = retarget.to_humanoid(template)
    times = np.arange(template.num_frames) / out_fps
    rotations = sample_at(restyled60.rotations, FPS, times)
    # What the foot lock did to the root (the pelvis height, the style's pace), as an offset
    # on the template's own roots.
    frames = np.arange(h60.num_frames) / FPS
    moved = h60.root_positions - restyled60.roots
    roots = h_template.root_positions - np.stack([np.interp(times, frames, moved[:, k]) for k in range(3)], axis=1)
    return retarget.to_source(h_template.replace(rotations=rotations, root_positions=roots), template=template)


def restyle_file(input_path, output_path, model=None, direction: str | None = None, intensity: float = 1.0,
                 hop: int = DEFAULT_HOP, fps: float | None = None, map_file=None, restyler=None, live: bool = False,
                 device: str = "cpu", style: str | None = None, feet: str = "auto", pace: str = "style",
                 performer_style: str | None = None) -> dict:
    """``style``: a style name or mix ("elderly", "elderly:0.5,youthful:0.5"), checked before
    anything is read; a pair model takes one of its two styles (the direction follows).
    ``direction``: a pair model's ("a2b" when neither it nor a style is given); refused for
    a model without directions and beside a style, which would each have been ignored.
    ``feet``: where planted feet go (``motion.footlock.FEET``); ``pace``: whose pace the
    output covers ground at (``motion.footlock.PACE_CHOICES``). ``performer_style``: the style
    the input is performed in (a multi-style model's; its share of a mix is the input as
    performed), refused by a pair model of another source."""
    from stylecast.motion.bvh import read_bvh, require_frames, write_bvh
    from stylecast.motion.footlock import check_feet, check_pace, feet_for
    from stylecast.motion.humanoid import load_user_map
    from stylecast.motion.resample import check_frame_rate

    from .restyler import Restyler

    from .styles import check_performer_style, parse_mix

    if fps is not None:
        check_frame_rate(fps)
    check_feet(feet)
    check_pace(pace)
    if performer_style is not None:
        check_performer_style(performer_style)
    if style is not None:
        parse_mix(style)  # unknown names are refused before the model and the clip are read
        if direction is not None:
            raise UserError(f"--direction {direction} and --style {style} both choose where the restyle goes; "
                            f"give one of them")
    restyler = restyler or Restyler.load(model, device=device)
    if direction is not None:
        restyler = restyler.with_direction(direction)  # a model without directions says so
    if style is not None:
        restyler = restyler.with_style(style)
    if performer_style is not None:
        restyler = restyler.with_performer_style(performer_style)
    user_map = load_user_map(map_file) if map_file else None
    clip = require_frames(read_bvh(Path(input_path)), str(input_path))
    out = restyle_clip(clip, restyler, hop, intensity, fps, user_map, live, feet_for(feet, restyler, pace))
    write_bvh(out, Path(output_path))
    return {"joints": len(out.skeleton), "frames": out.num_frames, "fps": out.fps, "model": restyler.name,
            "direction": restyler.direction, "from": restyler.source_style, "to": restyler.target_style}
