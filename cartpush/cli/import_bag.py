"""`cartpush import BAG -o LOG.csv --pose-topic T --wrench-topic T`: a ROS recording as a cart log.

`add_topic_options` / `topic_options` are the bag options for other commands that accept a bag in
place of a log (``cartpush.ros.load_any(path, **topic_options(args))``); this module stays light
(argparse only) so that they can import it at module level.
"""

from __future__ import annotations

import argparse
from typing import Any

DESCRIPTION = """\
Turn a ROS recording into a cart log (docs/log_format.md CSV): a ROS 1 .bag file, a ROS 2 bag
folder (sqlite3 or MCAP storage) or a single .mcap file. No ROS installation is needed.

The pose of the cart comes from --pose-topic (geometry_msgs/PoseStamped, TransformStamped,
PoseWithCovarianceStamped or nav_msgs/Odometry, or a custom type with the same fields whose
definition the bag carries) or from a TF frame (--pose-frame); x, y and the yaw of its 3-D
orientation make the planar pose. The wrench (geometry_msgs/WrenchStamped) is taken in the
frame its header names, moved into the world frame through /tf and /tf_static (interpolated in
time along the whole chain), and its torque re-expressed about the cart frame's origin.
Header stamps are used (--record-time: the recorder's); the wrench is interpolated at the pose
stamps; duplicate or out-of-order stamps are dropped and counted.

--list shows the topics (type, count, rate, usable as pose / wrench / tf) and the TF links.

Examples:
  cartpush import run.bag --list
  cartpush import run.bag -o run.csv --pose-topic /mocap/cart --wrench-topic /ft_sensor/wrench
  cartpush import rosbag2_run/ -o run.csv --pose-topic /odom --wrench-topic /wrench --world-frame map \\
      --negate-wrench --start 5 --end 65 --json
  cartpush estimate run.csv
"""


def add_topic_options(parser: argparse.ArgumentParser) -> None:
    """Add the options that say how to read a bag (pose, wrench, frames, window, clock) to ``parser``."""
    g = parser.add_argument_group("reading a ROS bag")
    g.add_argument(
        "--pose-topic",
        metavar="TOPIC",
        help="topic of the cart's pose (PoseStamped, TransformStamped, PoseWithCovarianceStamped, Odometry)",
    )
    g.add_argument("--pose-frame", metavar="FRAME", help="take the pose from this TF frame instead of a topic")
    g.add_argument("--wrench-topic", metavar="TOPIC", help="topic of the wrench on the cart (WrenchStamped)")
    g.add_argument(
        "--wrench-frame", metavar="FRAME", help="frame of the wrench when its header names none (overrides the header)"
    )
    g.add_argument(
        "--world-frame",
        metavar="FRAME",
        help="world frame {s} (default: the pose messages' frame; the root of --pose-frame's TF tree)",
    )
    g.add_argument(
        "--cart-frame",
        metavar="FRAME",
        help="TF frame that is the cart frame {b} (axle midpoint) when the tracked body's frame is not",
    )
    g.add_argument(
        "--negate-wrench",
        action="store_true",
        help="flip the wrench's sign (the sensor reports the force on the tool, not on the cart)",
    )
    g.add_argument("--start", type=float, metavar="S", help="keep pose samples from S seconds after the bag start")
    g.add_argument("--end", type=float, metavar="S", help="keep pose samples up to S seconds after the bag start")
    g.add_argument(
        "--record-time", action="store_true", help="use the recorder's receive times instead of the header stamps"
    )


def topic_options(args: argparse.Namespace) -> dict[str, Any]:
    """Return the keyword arguments of `cartpush.ros.import_bag` from the options of `add_topic_options`."""
    from cartpush.cli import options

    for name in ("start", "end"):
        value = getattr(args, name, None)
        if value is not None:
            options.finite(f"--{name}", value, why="seconds from the start of the recording")
    return {
        "pose_topic": args.pose_topic,
        "wrench_topic": args.wrench_topic,
        "pose_frame": args.pose_frame,
        "world_frame": args.world_frame,
        "negate_wrench": bool(args.negate_wrench),
        "start": args.start,
        "end": args.end,
        "use_record_time": bool(args.record_time),
        "cart_frame": args.cart_frame,
        "wrench_frame": args.wrench_frame,
    }


def register(subparsers) -> None:
    """Add the `import` subcommand."""
    parser = subparsers.add_parser(
        "import",
        help="turn a ROS 1/ROS 2 bag or an MCAP file into a cart log",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("bag", metavar="BAG", help="ROS 1 .bag, ROS 2 bag folder, or .mcap / .db3 file")
    parser.add_argument("-o", "--output", metavar="LOG", help="cart log to write (.csv or .csv.gz)")
    parser.add_argument(
        "--list", action="store_true", help="list topics, types, counts, rates and TF links; convert nothing"
    )
    parser.add_argument("--json", action="store_true", help="print only JSON")
    add_topic_options(parser)
    parser.set_defaults(func=run)


def _check_not_the_bag(bag: str, output: str) -> None:
    """Raise OptionError when the log to write (-o) is the bag itself or a file inside a ROS 2 bag folder."""
    import os

    from cartpush.errors import OptionError

    try:
        same = os.path.samefile(bag, output)
    except OSError:  # one of them does not exist (yet)
        same = os.path.realpath(bag) == os.path.realpath(output)
    inside = os.path.isdir(bag) and os.path.realpath(output).startswith(os.path.realpath(bag) + os.sep)
    if same or inside:
        where = "is the bag being imported" if same else "is inside the bag folder being imported"
        raise OptionError(f"-o {output}: {where}; writing it would destroy the bag, give a new .csv file")


def run(args: argparse.Namespace) -> int:
    """List the bag, or convert it and write the log; print a report (or JSON); return 0."""
    from cartpush.cli import options

    options.input_file(args.bag, "BAG")
    if not args.list:
        if not args.output:
            raise options.OptionError("give the log to write (-o LOG.csv), or --list to see what the bag holds")
        if not args.pose_topic and not args.pose_frame:
            raise options.OptionError(
                "give the cart's pose: --pose-topic TOPIC or --pose-frame FRAME (see `cartpush import BAG --list`)"
            )
        if args.pose_topic and args.pose_frame:
            raise options.OptionError("give either --pose-topic or --pose-frame, not both")
        if not args.wrench_topic:
            raise options.OptionError("give the wrench: --wrench-topic TOPIC (see `cartpush import BAG --list`)")
        kwargs = topic_options(args)
        options.writable_file(args.output, "-o")
        _check_not_the_bag(args.bag, args.output)
    from cart.jsonout import dumps_strict
    from cartpush.ros import import_bag, list_bag

    if args.list:
        summary = list_bag(args.bag)
        print(dumps_strict(summary.to_dict()) if args.json else summary.summary())
        return 0
    from cart.logs import write_log

    log, report = import_bag(args.bag, **kwargs)
    write_log(args.output, log)
    if args.json:
        out = report.to_dict()
        out["output"] = str(args.output)
        print(dumps_strict(out))
        return 0
    print(report.summary())
    print(f"wrote      {args.output}")
    for w in report.warnings:
        print(f"warning: {w}")
    return 0
