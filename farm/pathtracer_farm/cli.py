"""``pathtracer-farm render SCENE.dae... -f OUT --parts N``: a render cut into parts on Dask.

Every error is one line on stderr starting ``error:``, with exit code 2 (as the renderer's).
"""

import argparse
import os
import sys

from . import job as farm_job


class FarmError(Exception):
    """A one-line user-facing error."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse prints usage and exits; we want one line
        raise FarmError(message)


USAGE = """pathtracer-farm render SCENE.dae [SCENE.dae...] -f OUT --parts N
                       [--workers W | --scheduler tcp://HOST:8786] [--binary PATH]
                       [-r W H] [-s N] [-l N] [-m N] [-a B TOL] [-H] [--shading MODE]
                       [--seed N] [--sampler KIND] [--no-bvh] [-t N]
                       [--parts-dir DIR] [--retries R] [--connect-timeout S]"""


def _parser():
    p = _Parser(prog="pathtracer-farm", usage=USAGE, description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", parser_class=_Parser)
    r = sub.add_parser("render", usage=USAGE, help="render scenes in parts on a Dask cluster, then merge")
    r.add_argument("scenes", nargs="+", metavar="SCENE.dae", help="scene files (several: frames)")
    r.add_argument("-f", dest="output", required=True,
                   help="output .png or .exr; with several scenes it must hold {name} (the scene's stem)")
    r.add_argument("--parts", type=int, required=True, help="parts per scene (the renderer's plan)")
    where = r.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, help="start a LocalCluster of W worker processes (default 1)")
    where.add_argument("--scheduler", help="join a running cluster: tcp://HOST:8786")
    r.add_argument("--binary", help="the pathtracer binary, same path on every machine (default: on PATH)")
    r.add_argument("--parts-dir", help="where parts are kept (default OUT.parts; a rerun resumes from it)")
    r.add_argument("--retries", type=int, default=2, help="retries of a failed part (default 2)")
    r.add_argument("--connect-timeout", type=float, default=10.0, help="seconds to reach the scheduler")
    r.add_argument("-r", nargs=2, metavar=("W", "H"))
    for flag in ("-s", "-l", "-m", "-t", "--shading", "--seed", "--sampler"):
        r.add_argument(flag)
    r.add_argument("-a", nargs=2, metavar=("B", "TOL"))
    r.add_argument("-H", action="store_true")
    r.add_argument("--no-bvh", action="store_true")
    return p


def renderer_flags(a):
    """The renderer flags to pass on, in the renderer's spelling."""
    flags = []
    if a.r:
        flags += ["-r", *a.r]
    for name, value in (("-s", a.s), ("-l", a.l), ("-m", a.m), ("--shading", a.shading),
                        ("--seed", a.seed), ("--sampler", a.sampler)):
        if value is not None:
            flags += [name, value]
    if a.a:
        flags += ["-a", *a.a]
    if a.H:
        flags.append("-H")
    if a.no_bvh:
        flags.append("--no-bvh")
    return flags


def main(argv=None):
    try:
        args = _parser().parse_args(argv)
        if args.command != "render":
            raise FarmError("expected a command: pathtracer-farm render ... (see --help)")
        return farm_job.run(args, renderer_flags(args))
    except FarmError as e:
        message = " ".join(str(e).split("\n"))
        print(f"error: {message}", file=sys.stderr)
        return 2
    except farm_job.JobError as e:
        message = " ".join(str(e).split("\n"))
        print(f"error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted (rerun the same command to resume)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
