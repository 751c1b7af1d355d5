"""`python -m vizzy_runtime.bag record|play|info|reindex`: a thin command line over the API
(the `vizzy bag` CLI is the user-facing one)."""

from __future__ import annotations

import argparse
import logging
import sys

from . import BagError, Player, Recorder, bag_info, default_bag_name, reindex


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='python -m vizzy_runtime.bag')
    sub = parser.add_subparsers(dest='cmd', required=True)
    rec = sub.add_parser('record', help='record topics into a new bag')
    rec.add_argument('topics', nargs='*', help='topics (default: all)')
    rec.add_argument('-o', '--output', default=None, help='bag directory to create')
    rec.add_argument('-d', '--duration', type=float, default=None, help='seconds')
    rec.add_argument('--include-hidden', action='store_true')
    play = sub.add_parser('play', help='publish a bag')
    play.add_argument('bag')
    play.add_argument('-r', '--rate', type=float, default=1.0)
    play.add_argument('--topics', nargs='+', default=None)
    play.add_argument('-l', '--loop', action='store_true')
    play.add_argument('--wait-for-subscribers', type=float, default=0.0, metavar='SECONDS')
    info = sub.add_parser('info', help='summarize a bag')
    info.add_argument('bag')
    idx = sub.add_parser('reindex', help='repair a killed recording, rebuild metadata.yaml')
    idx.add_argument('bag')
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format='[%(levelname)s] %(message)s')
    try:
        if args.cmd == 'record':
            counts = Recorder(args.output or default_bag_name(), args.topics or None,
                              include_hidden=args.include_hidden).run(args.duration)
            for topic, count in sorted(counts.items()):
                print(f'{topic}: {count}')
        elif args.cmd == 'play':
            counts = Player(args.bag, rate=args.rate, topics=args.topics, loop=args.loop,
                            wait_for_subscribers=args.wait_for_subscribers).run()
            for topic, count in sorted(counts.items()):
                print(f'{topic}: {count}')
        elif args.cmd == 'info':
            print(bag_info(args.bag), end='')
        else:
            reindex(args.bag)
    except BagError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
