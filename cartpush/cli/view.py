"""`cartpush view`: show a cart log, a Table I test or a robot in Meshcat (live, or as an offline HTML page)."""

from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path

from cartpush.cli import options
from cartpush.cli.import_bag import add_topic_options, topic_options

HELP = "show a cart log, a Table I test, a robot or a cart file in Meshcat"
DESCRIPTION = """\
Show a scene in Meshcat: a cart log (animated cart, force arrow, path), a
Table I simulation test 1..11 (robot pushing the cart, force, contact point,
true vs estimated CoM), one robot (`--robot`; `--robot pushing` shows the
Ridgeback + iiwa holding the cart's handle), or a MuJoCo cart file
(`--cart-model`: the cart `push --plant mujoco --cart-model` pushes, drawn
from the file's own bodies, with its handle sites).

Without --html it serves the scene on localhost, prints the URL and keeps
serving until Ctrl-C. With --html it writes a self-contained page (opens
offline in any browser) and exits. Animated pages play when opened and loop;
the box in the bottom-left corner has a pause button, the time, live values
and the legend; OUT.html#t=12 opens the page paused at 12 s. The camera
starts on the robot and the cart and follows them.

Examples:
  cartpush view --robot ridgeback_iiwa
  cartpush view --scenario 6 --html test6.html
  cartpush view run.csv --html run.html
  cartpush view --cart-model examples/carts/hospital_bed.xml --html bed.html
"""


#: How an animated page is used, printed after writing one (`push --html`, `demo` print it too).
PLAYER_HINT = (
    "it plays when opened and loops: pause with the button in its bottom-left corner (or the space bar); "
    "{page}#t=12 opens it paused at 12 s; the corner's legend says what each colour and arrow means"
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `view` subcommand."""
    parser = subparsers.add_parser(
        "view", help=HELP, description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("log", nargs="?", help="cart log (.csv or .csv.gz, docs/log_format.md) or a ROS bag")
    source.add_argument("--scenario", type=int, metavar="N", help="Table I simulation test N (1..11)")
    source.add_argument(
        "--robot",
        metavar="NAME|PROFILE.toml",
        help="a robot of `robots.available()`, a robot profile file, or 'pushing'",
    )
    source.add_argument(
        "--cart-model",
        metavar="FILE.xml",
        help="a MuJoCo cart file (the contract is in docs/mujoco.md), drawn from its own bodies and handle sites",
    )
    parser.add_argument("--html", metavar="OUT.html", help="write a static page instead of serving")
    parser.add_argument(
        "--duration", type=float, default=30.0, metavar="S", help="simulated seconds for --scenario (default 30)"
    )
    add_topic_options(parser)
    parser.set_defaults(func=run)


def validate(args: argparse.Namespace) -> None:
    """Check the options before any work (raise OptionError)."""
    if args.scenario is not None:
        if not 1 <= args.scenario <= 11:
            raise options.OptionError(f"--scenario must be a Table I test between 1 and 11, got {args.scenario}")
        options.duration(args.duration, rate=100.0)
    elif args.duration != 30.0:
        raise options.OptionError(
            f"--duration {args.duration:g}: the simulated seconds of --scenario; a log is shown whole or from --start "
            "to --end"
        )
    if args.html:
        options.writable_file(args.html, "--html", create=False)


def build_scene(args: argparse.Namespace, serve: bool):
    """Return the scene the arguments ask for (a `wholebody.viz.Scene`)."""
    from wholebody.push.scenes import pushing_scene
    from wholebody.viz import log_scene, robot_scene

    if args.scenario is not None:
        options.duration(args.duration, rate=100.0)
        from wholebody.push.scenes import scenario_scene

        return scenario_scene(args.scenario, duration=args.duration, serve=serve)
    if args.robot is not None:
        if args.robot == "pushing":
            return pushing_scene(serve=serve)
        return robot_scene(args.robot, serve=serve)
    if args.cart_model is not None:
        from wholebody.push.cart_file import mujoco_warnings
        from wholebody.viz.mjcf import cart_file_scene

        # `cart_file_scene` reads the file with `cart_file.load_cart_file`, the checks of `push --cart-model` (a
        # fault: one line, exit 2), and MuJoCo's warnings are kept off stderr and out of a MUJOCO_LOG.TXT
        with mujoco_warnings():
            return cart_file_scene(args.cart_model, serve=serve)
    from cartpush.ros import load_any

    log = load_any(args.log, **topic_options(args))
    for w in log.warnings:  # the reader's plausibility notes (units, glitches), one line each
        print(f"cartpush view: warning: {w}", file=sys.stderr)
    return log_scene(log, serve=serve)


def run(args: argparse.Namespace) -> int:
    """Write the page (--html) or serve the scene until Ctrl-C; return the exit code."""
    validate(args)
    if args.html:
        out = Path(args.html)
        with build_scene(args, serve=False) as scene:
            scene.save_html(out)
            animated = scene.animation_duration() > 0
        print(f"wrote {out} ({out.stat().st_size / 1e6:.1f} MB); open it in a browser (works offline)")
        if animated:
            print(PLAYER_HINT.format(page=out.name))
        return 0
    previous = signal.signal(signal.SIGTERM, _interrupt)  # stop the server on SIGTERM too
    try:
        with build_scene(args, serve=True) as scene:
            print(f"Meshcat scene at {scene.url} (Ctrl-C to stop)", flush=True)
            if scene.animation_duration() > 0:
                print("the live viewer plays the animation; play/pause/time in its Animations panel", flush=True)
            try:
                while True:
                    time.sleep(1.0)
            except KeyboardInterrupt:
                print("stopped", file=sys.stderr)
    finally:
        signal.signal(signal.SIGTERM, previous)
    return 0


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt
