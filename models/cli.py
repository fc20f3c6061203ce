"""`stylecast train`, `stylecast restyle` and `stylecast eval`. Torch is imported inside
the command functions so `stylecast --help` stays fast."""

from __future__ import annotations

import argparse
from pathlib import Path


def _positive_int(s: str) -> int:
    v = int(s)
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {s}")
    return v


def _count(s: str) -> int:
    v = int(s)
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be zero or a positive integer, got {s}")
    return v


def _unit(s: str) -> float:
    v = float(s)
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"must be between 0 and 1, got {s}")
    return v


def _add_data_options(p: argparse.ArgumentParser) -> None:
    """The options of every command that reads the dataset: where it is, the decoded-clip
    cache and torch's CPU threads."""
    p.add_argument("--data", type=Path, help="the Bandai dataset-2 'data' folder (default ../shared/...)")
    p.add_argument("--cache", type=Path, help="cache folder for decoded clips (default ~/.cache/stylecast)")
    p.add_argument("--threads", type=_positive_int, help="torch CPU threads (default: torch's choice)")


def register(sub: argparse._SubParsersAction) -> None:
    for add in (_add_train, _add_tune_holds, _add_tune_steps, _add_train_reader, _add_restyle, _add_eval):
        add(sub)


def _add_train(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("train", help="train a CycleGAN restyler between two styles of the Bandai dataset-2")
    p.add_argument("--style-a", default="normal", help="style A (default normal)")
    p.add_argument("--style-b", default="exhausted", help="style B (default exhausted)")
    p.add_argument("--loss", choices=("cycle-diff", "coherence"), default="cycle-diff",
                   help="cycle-diff: the paper's temporal-difference loss; coherence: the Adult2Child baseline")
    p.add_argument("--styles", choices=("pair", "all"), default="pair",
                   help="pair: a CycleGAN between --style-a and --style-b (default); all: one multi-style model "
                        "for every dataset-2 style, the style a learned code (AdaIN)")
    p.add_argument("--epochs", type=_positive_int, help="default 90 (pair), 80 (all)")
    p.add_argument("--batch-size", type=_positive_int, default=32)
    p.add_argument("--words-per-epoch", type=_positive_int,
                   help="words drawn per epoch: of each style for a pair (default 1024), of all styles "
                        "together for --styles all (default 2048)")
    p.add_argument("--generator", default="temporal", metavar="temporal|graph",
                   help="--styles all: convolutions over time only (temporal, default) or over the skeleton's "
                        "bone graph as well (graph, seed 003)")
    p.add_argument("--lambda-identity", type=float, default=0.0,
                   help="--styles all: weight of |G(x, own style) - x| (default 0 = off)")
    p.add_argument("--lambda-mismatch", type=float, default=0.0,
                   help="--styles all: weight of the discriminator's mismatch term, real words of other styles "
                        "scored as fake on a style's head (default 0 = off)")
    p.add_argument("--lambda-step", type=float, default=0.0,
                   help="--styles all: weight of the step term, a restyle's feet stepping higher than its "
                        "target style's, in cm (default 0 = off)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--ema", type=float, metavar="DECAY",
                   help="the model written is the generators' weight average over training with this decay "
                        "(default 0.999; the last weights go to model-raw.safetensors); 0 = the last weights")
    p.add_argument("--representation", choices=("euler", "6d"), default="euler")
    p.add_argument("--knots", type=int,
                   help="control points of the smooth (cubic B-spline) correction over a word; 0 = a free "
                        "full-rate correction (default: the shipped models' setting)")
    p.add_argument("--width", type=_positive_int,
                   help="the generator's hidden channels (default: the shipped models' 96)")
    p.add_argument("--blocks", type=_positive_int,
                   help="the generator's residual blocks at half rate (default: the shipped models' 3)")
    p.add_argument("--lambda-gram", type=float,
                   help="weight of the velocity Gram-matrix dynamics-style loss (seed 004): a pair's restyles "
                        "against the batch's real target words (default 0 = off); with --styles all against the "
                        "mean of the target style's training words of the input's action (models/dynamics_term.py; "
                        "default 1, 0 = off)")
    p.add_argument("--lambda-overlap", type=float, default=0.0,
                   help="weight of the loss that makes overlapping words of a take agree (what the stream "
                        "switches between); default 0 = off")
    p.add_argument("--lambda-action", type=float, default=0.0,
                   help="weight of the loss that keeps the input's action (a frozen action classifier's "
                        "cross-entropy on the restyled words); default 0 = off")
    p.add_argument("--action-view", choices=("channels", "positions"), default="channels",  # train.ACTION_VIEWS
                   help="what the action-content classifier sees: the generator's channels (default) or the "
                        "joints' positions by forward kinematics, as the evaluation's judges do (pair models)")
    p.add_argument("--lambda-style", type=float, default=0.0,
                   help="weight of the loss that makes the restyle read as the target among all seven styles "
                        "(a frozen style classifier's cross-entropy); default 0 = off")
    p.add_argument("--lambda-position-adv", type=float, default=0.0,
                   help="weight of a second adversarial term: discriminators over the joints' world positions by "
                        "forward kinematics, what a viewer and the evaluation's judges see (pair models); "
                        "default 0 = off")
    p.add_argument("--lambda-hold", type=float, default=0.0,
                   help="weight of the loss that keeps a hand or the head still where the input holds it still "
                        "against the hips (pair models); default 0 = off")
    p.add_argument("--hold-from", type=int, default=0, metavar="EPOCH",
                   help="train the first EPOCH epochs without the hold term, then with it (default 0: from the "
                        "start); the epochs before it are the same run as without the term")
    p.add_argument("--mirror", action="store_true",
                   help="train on every take and its left-right mirror image (a left turn mirrored is a right "
                        "turn); the epoch's size is unchanged")
    p.add_argument("--feet", metavar="input|stance|path",
                   help="the foot lock `serve` and `restyle` use with this model under --feet auto, recorded in "
                        "the checkpoint (default: its kind's own, input for a pair, stance for --styles all)")
    p.add_argument("--out", type=Path, required=True, help="output folder (checkpoints, losses.csv, model)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its last epoch")
    p.add_argument("--max-words", type=_positive_int, help="use at most N training words per style (tiny CI runs)")
    p.add_argument("--device", default="auto", help="auto (CUDA when present), cpu or cuda[:N]")
    _add_data_options(p)
    p.add_argument("--no-progress", action="store_true", help="print one line per epoch instead of a bar")
    p.set_defaults(func=run_train)


def _add_tune_holds(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("tune-holds", help="tune a trained pair or multi-style model to hold a hand or the head still "
                                           "where the input holds it, changing nothing else it can help")
    p.add_argument("--model", default="normal2exhausted",
                   help="the pair or multi-style model to tune (a file or a shipped name)")
    p.add_argument("--out", type=Path, required=True, help="the tuned model's file (.safetensors)")
    p.add_argument("--lambda-hold", type=float, help="weight of the hold term (default 4)")
    p.add_argument("--distil", type=float, help="weight of the distillation to the model as it was (default 100)")
    p.add_argument("--epochs", type=_positive_int,
                   help="passes over the training words (default 10 for a pair model, 3 for a multi-style one)")
    p.add_argument("--seed", type=int, default=3)
    _add_data_options(p)
    p.set_defaults(func=run_tune_holds)


def _add_tune_steps(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("tune-steps", help="tune a trained multi-style model so its restyles step no higher than "
                                           "their target style does, changing nothing else it can help")
    p.add_argument("--model", default="multistyle", help="the multi-style model to tune (a file or a shipped name)")
    p.add_argument("--out", type=Path, required=True, help="the tuned model's file (.safetensors)")
    p.add_argument("--lambda-step", type=float, help="weight of the step term, per cm (default 1)")
    p.add_argument("--distil", type=float, help="weight of the distillation to the model as it was (default 100)")
    p.add_argument("--epochs", type=_positive_int, help="passes over every style's training words (default 4)")
    p.add_argument("--seed", type=int, default=1)
    _add_data_options(p)
    p.set_defaults(func=run_tune_steps)


def _add_train_reader(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("train-reader", help="train the style reader of a multi-style model (--performer-style auto) "
                                             "and store it in the model's file beside the generator")
    p.add_argument("--model", default="multistyle", help="the multi-style model (a file or a shipped name)")
    p.add_argument("--out", type=Path, help="write the model with its reader here (.safetensors; default: in place)")
    p.add_argument("--epochs", type=_positive_int, help="passes over the training words (default 12)")
    p.add_argument("--seed", type=int, default=0)
    _add_data_options(p)
    p.set_defaults(func=run_train_reader)


def _add_restyle(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("restyle", help="restyle a BVH clip with a trained model")
    p.add_argument("input", type=Path)
    p.add_argument("-o", "--output", type=Path, required=True)
    p.add_argument("--model", default=None, help="checkpoint path or shipped name (default normal2exhausted)")
    p.add_argument("--direction", choices=("a2b", "b2a"), help="a pair model's direction (default a2b)")
    p.add_argument("--style", help="target style, or a mix NAME:W,NAME:W (e.g. elderly:0.5,youthful:0.5), for "
                                   "--model multistyle; a pair model takes one of its two styles")
    p.add_argument("--performer-style", metavar="NAME|auto",
                   help="the style the input is performed in (default normal), for --model multistyle: its share "
                        "of a style mix is the input as performed; auto reads it from each word of the input")
    p.add_argument("--intensity", type=_unit, default=1.0, help="0 = input, 1 = fully restyled")
    p.add_argument("--hop", type=_positive_int,
                   help="frames between words (1..60; 60 = no overlap); default: as `serve`")
    p.add_argument("--fps", type=float, help="frame rate of the output (default: the input's)")
    p.add_argument("--live", action="store_true",
                   help="render as the live daemon does (no mirrored pre-roll: the first words hold the first "
                        "frame): the same frames `stylecast serve` sends for this clip")
    p.add_argument("--map", type=Path, help="JSON/TOML table of source joint name -> humanoid bone")
    p.add_argument("--feet", default="auto", metavar="auto|input|stance|path",
                   help="planted feet on the input's own ankles (input), where the restyled legs stand "
                        "(stance), or on the input's ankles with the feet in the air on the input's own path "
                        "too (path); default auto: the model's own, as `serve --feet`")
    p.add_argument("--pace", default="style", metavar="style|input",
                   help="cover ground at the target style's pace (style, the default: an exhausted run is "
                        "slower, its strides shorter) or at the input's own (input: the root's path passes "
                        "through), as `serve --pace`")
    p.add_argument("--threads", type=_positive_int, help="torch CPU threads")
    p.add_argument("--device", default="auto", help="where the model runs: auto (CUDA when present), cpu or cuda[:N]")
    p.set_defaults(func=run_restyle)


def _add_eval(sub: argparse._SubParsersAction) -> None:
    from .judges import DYNAMICS_PANEL, PANEL, RECURRENT_PANEL  # no torch at import time

    p = sub.add_parser("eval", help="judge a model on held-out files: style, action, FMD, jerk, foot slide, "
                                     "timing, seams, against the input and the baselines")
    p.add_argument("--model", default=None, help="model under test (default normal2exhausted)")
    p.add_argument("--direction", choices=("a2b", "b2a"), help="a pair model's direction (default a2b)")
    p.add_argument("--target", action="append", metavar="STYLE",
                   help="target style to measure (repeat for several, or 'all': every style but the source); "
                        "default: the model's target (a multistyle model needs it)")
    p.add_argument("--source", metavar="STYLE",
                   help="style of the held-out clips to restyle (default: the model's source; normal for a "
                        "multistyle model, which takes any)")
    p.add_argument("--variant", action="append", default=[], metavar="NAME=PATH",
                   help="another model to measure beside it (repeat)")
    p.add_argument("--out", type=Path, required=True, help="report folder (report.md, plots, metrics.json)")
    p.add_argument("--max-files", type=_positive_int, help="evaluate on at most N held-out files per style")
    p.add_argument("--hop", type=_positive_int, help="hop of the restyle (default: serve's)")
    _add_data_options(p)
    p.add_argument("--seed", type=int, default=0, help="seed of the first judge of each kind (the others: seed+1, ...)")
    p.add_argument("--judges", type=_positive_int, default=PANEL,
                   help=f"convolutional judges of each kind in the panel (default {PANEL}); the goals are read on "
                        "the worst judge of the panel")
    p.add_argument("--recurrent-judges", type=_count, default=RECURRENT_PANEL,
                   help=f"recurrent (GRU) judges of each kind beside them, another design with other quirks "
                        f"(default {RECURRENT_PANEL}; 0: none)")
    p.add_argument("--dynamics-judges", type=_count, default=DYNAMICS_PANEL,
                   help=f"style judges that see only velocities, a stricter style goal (default {DYNAMICS_PANEL}; "
                        "0: none)")
    p.add_argument("--fresh-judges", action="store_true",
                   help="train the judges anew instead of reading the panel an earlier evaluation trained on the "
                        "same windows with the same code from the cache folder (it is overwritten)")
    p.set_defaults(func=run_eval)


def _threads(n):
    if n:
        import torch

        torch.set_num_threads(n)


def _check_ema(decay: float | None) -> None:
    from stylecast.motion.errors import UserError

    if decay is not None and not (decay == 0 or 0 < decay < 1):
        raise UserError(f"--ema must be 0 (off) or a decay between 0 and 1 such as 0.999, got {decay:g}")


def _check_lock(feet: str | None) -> None:
    """``train --feet``: a lock the checkpoint can name ("auto" is what serving does with it)."""
    from stylecast.motion.errors import UserError
    from stylecast.motion.footlock import FEET

    if feet is not None and feet not in FEET:
        raise UserError(f"--feet {feet!r} is not a foot lock a model can name; use one of {', '.join(FEET)}")


def _check_generator(name: str, styles: str) -> None:
    from stylecast.motion.errors import UserError

    from .multistyle import GENERATORS

    if name not in GENERATORS:
        raise UserError(f"--generator {name!r} is not known; use one of {', '.join(GENERATORS)}")
    if name != "temporal" and styles != "all":
        raise UserError(f"--generator {name} is a multi-style generator; add --styles all")


def _non_negative(**weights) -> None:
    """One sentence for the first weight given below 0 (None: not given); names are the
    flags' with dashes for underscores."""
    from stylecast.motion.errors import UserError

    for name, value in weights.items():
        if value is not None and not value >= 0:
            raise UserError(f"--{name.replace('_', '-')} must be 0 or more, got {value:g}")


def _given(**options) -> dict:
    """The options given on the command line (None = not given: the config's default)."""
    return {k: v for k, v in options.items() if v is not None}


# The largest generator ``train`` builds: a live restyler runs a word in milliseconds (the
# shipped ones are 96 channels x 3 blocks; the widest measured, 192 x 6, took 2.7x as long).
MAX_WIDTH, MAX_BLOCKS = 1024, 32


def _network_options(args) -> dict:
    """The generator's settings given on the command line, as the network config's fields;
    a size no live restyler could run is refused in one sentence before any data is read."""
    from stylecast.motion.errors import UserError

    for flag, value, most in (("--width", args.width, MAX_WIDTH), ("--blocks", args.blocks, MAX_BLOCKS)):
        if value is not None and value > most:
            raise UserError(f"{flag} {value} is more than a live restyler can run; choose at most {most}")
    return _given(correction_knots=args.knots, g_hidden=args.width, g_blocks=args.blocks)


def run_train_multistyle(args) -> int:
    from stylecast.motion.errors import UserError

    from .multistyle import GENERATORS, MultiStyleConfig
    from .train_multistyle import MultiStyleTrainConfig, load_all_styles, train_multistyle

    _non_negative(lambda_identity=args.lambda_identity, lambda_action=args.lambda_action,
                  lambda_mismatch=args.lambda_mismatch, lambda_step=args.lambda_step, lambda_gram=args.lambda_gram)
    try:
        net = MultiStyleConfig(**GENERATORS[args.generator], **_network_options(args))
    except ValueError as exc:
        raise UserError(f"--knots: {exc}") from None
    cfg = MultiStyleTrainConfig(batch_size=args.batch_size, seed=args.seed, representation=args.representation,
                                max_words=args.max_words, lambda_identity=args.lambda_identity,
                                lambda_mismatch=args.lambda_mismatch, lambda_action=args.lambda_action,
                                lambda_step=args.lambda_step, network=net,
                                feet=args.feet, mirror=args.mirror,
                                **_given(ema=args.ema, epochs=args.epochs, words_per_epoch=args.words_per_epoch,
                                         lambda_gram=args.lambda_gram))
    train, val, actions = load_all_styles(cfg, args.data, args.cache, progress=not args.no_progress)
    from . import data as D

    skeleton = D.bandai_skeleton(D.list_files(args.data)) if cfg.lambda_step > 0 else None
    train_multistyle(cfg, args.out, train, val, device=args.device, progress=not args.no_progress,
                     resume=args.resume, actions=actions, skeleton=skeleton)
    return 0


def run_train(args) -> int:
    from stylecast.motion.errors import UserError

    from .device import pick_device
    from .networks import NetworkConfig
    from .train import TrainConfig, load_training_words, train

    _threads(args.threads)
    _check_ema(args.ema)
    _check_lock(args.feet)
    pick_device(args.device)  # a missing CUDA device is refused before minutes of data loading
    _check_generator(args.generator, args.styles)
    if args.styles == "all":
        if args.lambda_style:
            raise UserError("--lambda-style is for a pair model; drop it or drop --styles all")
        if args.action_view != "channels":
            raise UserError("--action-view is for a pair model; drop it or drop --styles all")
        if args.lambda_hold:
            raise UserError("--lambda-hold is for a pair model; drop it or drop --styles all")
        if args.lambda_position_adv:
            raise UserError("--lambda-position-adv is for a pair model; drop it or drop --styles all")
        return run_train_multistyle(args)
    for flag, value in (("--lambda-mismatch", args.lambda_mismatch), ("--lambda-step", args.lambda_step)):
        if value:
            raise UserError(f"{flag} is for --styles all; drop it or add --styles all")
    cfg = TrainConfig(style_a=args.style_a, style_b=args.style_b, loss=args.loss,
                      **_given(epochs=args.epochs, words_per_epoch=args.words_per_epoch),
                      batch_size=args.batch_size, seed=args.seed,
                      representation=args.representation, max_words=args.max_words,
                      **_given(lambda_gram=args.lambda_gram), lambda_overlap=args.lambda_overlap,
                      lambda_action=args.lambda_action,
                      lambda_style=args.lambda_style, lambda_hold=args.lambda_hold, hold_from=args.hold_from,
                      lambda_position_adv=args.lambda_position_adv, feet=args.feet, mirror=args.mirror,
                      action_view=args.action_view, **_given(ema=args.ema))
    from .styles import check_style

    for name in (args.style_a, args.style_b):
        check_style(name)  # before minutes of data loading
    if args.style_a == args.style_b:
        raise UserError(f"--style-a and --style-b are both {args.style_a!r}; choose two different styles")
    _non_negative(lambda_gram=args.lambda_gram, lambda_overlap=args.lambda_overlap, lambda_action=args.lambda_action,
                  lambda_style=args.lambda_style, lambda_hold=args.lambda_hold,
                  lambda_position_adv=args.lambda_position_adv)
    if args.hold_from and not 0 < args.hold_from < cfg.epochs:
        raise UserError(f"--hold-from {args.hold_from} leaves no epoch with the hold term in {cfg.epochs} epochs; "
                        f"choose an epoch from 1 to {cfg.epochs - 1}, or raise --epochs")
    if args.hold_from and not args.lambda_hold:
        raise UserError("--hold-from needs --lambda-hold above 0; add it or drop --hold-from")
    try:
        cfg.network = NetworkConfig(**_network_options(args))
    except ValueError as exc:
        raise UserError(f"--knots: {exc}") from None
    sets = load_training_words(cfg, args.data, args.cache, progress=not args.no_progress)
    from . import data as D
    from .content import ActionLabels
    from .style_target import load_style_words

    styles = (load_style_words(cfg, sets, args.data, args.cache, progress=not args.no_progress)
              if cfg.lambda_style > 0 else None)
    needs_skeleton = cfg.action_view == "positions" or cfg.lambda_hold > 0 or cfg.lambda_position_adv > 0
    skeleton = D.bandai_skeleton(D.list_files(args.data)) if needs_skeleton else None
    a, b = sets[(cfg.style_a, "train")], sets[(cfg.style_b, "train")]
    train(cfg, args.out, a.words, b.words, sets[(cfg.style_a, "val")].words, sets[(cfg.style_b, "val")].words,
          resume=args.resume, device=args.device, progress=not args.no_progress,
          next_a=D.next_words(a), next_b=D.next_words(b), actions=ActionLabels.of(sets),
          styles=styles, skeleton=skeleton)
    return 0


def _run_tuning(args, tune, **weights) -> int:
    """``tune-holds`` and ``tune-steps``: the weights checked, then ``tune(model, out, ...)``."""
    from stylecast.motion.errors import UserError

    _non_negative(**weights)
    if args.out.suffix != ".safetensors":
        raise UserError(f"--out {args.out} must name a .safetensors file, for example runs/tuned.safetensors")
    _threads(args.threads)
    tune(args.model, args.out, seed=args.seed, data_dir=args.data, cache_dir=args.cache,
         **_given(**weights, epochs=args.epochs))
    return 0


def run_tune_holds(args) -> int:
    from .holds import tune_holds

    return _run_tuning(args, tune_holds, lambda_hold=args.lambda_hold, distil=args.distil)


def run_tune_steps(args) -> int:
    from .steps import tune_steps

    return _run_tuning(args, tune_steps, lambda_step=args.lambda_step, distil=args.distil)


def run_train_reader(args) -> int:
    from stylecast.motion.errors import UserError

    from .style_reader import add_reader

    if args.out is not None and args.out.suffix != ".safetensors":
        raise UserError(f"--out {args.out} must name a .safetensors file, for example runs/multistyle.safetensors")
    _threads(args.threads)
    add_reader(args.model, args.out, seed=args.seed, data_dir=args.data, cache_dir=args.cache,
               **_given(epochs=args.epochs))
    return 0


def run_restyle(args) -> int:
    from .restyle import restyle_file

    _threads(args.threads)
    from stylecast.motion.words import DEFAULT_HOP

    info = restyle_file(args.input, args.output, model=args.model, direction=args.direction,
                        intensity=args.intensity, hop=args.hop or DEFAULT_HOP, fps=args.fps, map_file=args.map,
                        live=args.live, device=args.device, style=args.style, feet=args.feet,
                        pace=args.pace, performer_style=args.performer_style)
    print(f"wrote {args.output}: {info['joints']} joints, {info['frames']} frames at {info['fps']:g} fps "
          f"({info['model']}{', ' + info['direction'] if info['direction'] else ''}: {info['from']} -> {info['to']})")
    return 0


def run_eval(args) -> int:
    from stylecast.motion.errors import UserError
    from stylecast.motion.words import DEFAULT_HOP

    from .eval import evaluate

    variants = {}
    for item in args.variant:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise UserError(f"--variant {item!r} is not NAME=PATH; for example --variant k12=runs/k12/model.safetensors")
        if name in variants:
            raise UserError(f"--variant {name} is given twice; give each variant its own name")
        variants[name] = path
    _threads(args.threads)
    path = evaluate(args.model, args.out, variants, max_files=args.max_files, hop=args.hop or DEFAULT_HOP,
                    data_dir=args.data, cache_dir=args.cache, seed=args.seed, direction=args.direction,
                    targets=args.target, source=args.source, panel=args.judges, dynamics=args.dynamics_judges,
                    recurrent=args.recurrent_judges, fresh_judges=args.fresh_judges)
    print(f"wrote {path}")
    return 0
