"""`vizzy_head_urdf`: print the head's URDF (core.urdf.head_urdf) or write it to a file.

    vizzy_head_urdf                 # to stdout
    vizzy_head_urdf -o vizzy.urdf   # to a file
    vizzy_head_urdf --world         # rooted at the simulator's `world` frame instead of base_link

It is generated from core/kinematics.py and the MuJoCo model each time, so a file written by
this command is a snapshot: the repository keeps no copy. robot_state_publisher takes it as its
`robot_description` parameter (launch/robot_state_publisher.launch.py does that at launch time).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from vizzy_sim_bridge.core.urdf import head_urdf


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='vizzy_head_urdf', description="Print the Vizzy head's URDF, generated from the "
        "kinematics and the MuJoCo model the simulator uses.")
    parser.add_argument('-o', '--output', type=Path, help='write it to this file instead of stdout')
    parser.add_argument('--world', action='store_true',
                        help='include the fixed world -> base_link joint the simulator publishes')
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    text = head_urdf(world=args.world)
    if args.output is None:
        sys.stdout.write(text)
        return 0
    try:
        args.output.write_text(text)
    except OSError as exc:
        print(f'vizzy_head_urdf: cannot write {args.output}: {exc.strerror or exc}',
              file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
