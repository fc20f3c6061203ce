"""`stylecast info` and `stylecast convert`."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("info", help="describe a BVH file: joints, frames, fps, humanoid mapping")
    p.add_argument("file", type=Path)
    p.add_argument("--map", type=Path, help="JSON/TOML table of source joint name -> humanoid bone")
    p.set_defaults(func=run_info)

    p = sub.add_parser("convert", help="resample a BVH, or rewrite it on the canonical humanoid")
    p.add_argument("input", type=Path)
    p.add_argument("-o", "--output", type=Path, required=True)
    p.add_argument("--fps", type=float, help="resample to this frame rate")
    p.add_argument("--humanoid", action="store_true",
                   help="write the canonical humanoid skeleton (T-pose rest, Unity bone names, centimetres)")
    p.add_argument("--map", type=Path, help="JSON/TOML table of source joint name -> humanoid bone")
    p.set_defaults(func=run_convert)


def _user_map(path: Path | None):
    from .humanoid import load_user_map

    return load_user_map(path) if path else None


def run_info(args) -> int:
    from .bvh import read_bvh
    from .errors import UserError
    from .humanoid import HUMANOID_BONES, Retarget

    clip = read_bvh(args.file)
    sk = clip.skeleton
    print(f"file      {args.file}")
    print(f"joints    {len(sk)}: {', '.join(sk.names)}")
    print(f"frames    {clip.num_frames}")
    print(f"fps       {clip.fps:g}")
    print(f"duration  {clip.duration:.3f} s")
    try:
        retarget = Retarget.for_clip(clip, _user_map(args.map))
    except UserError as exc:
        print(f"humanoid  not mappable: {exc}")
        return 0
    mapped = retarget.mapped
    print(f"humanoid  {len(mapped)}/{len(HUMANOID_BONES)} bones mapped")
    for bone in HUMANOID_BONES:
        print(f"  {bone:<14} {mapped.get(bone, '-- missing (identity)')}")
    return 0


def run_convert(args) -> int:
    from .bvh import read_bvh, write_bvh
    from .humanoid import Retarget
    from .resample import check_frame_rate, resample

    if args.fps is not None:
        check_frame_rate(args.fps)  # before the file is read, as restyle checks it
    clip = read_bvh(args.input)
    if args.humanoid:
        clip = Retarget.for_clip(clip, _user_map(args.map)).to_humanoid(clip)
    if args.fps is not None:
        clip = resample(clip, args.fps)
    write_bvh(clip, args.output)
    print(f"wrote {args.output}: {len(clip.skeleton)} joints, {clip.num_frames} frames at {clip.fps:g} fps")
    return 0
