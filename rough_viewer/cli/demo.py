"""``rough-viewer demo``: list the demo data sets and write them to files.

    rough-viewer demo --list
    rough-viewer demo generate NAME --out FILE.laz [--alpha DEG] [--beta DEG] [--force]

``generate outcrop`` rewrites the bundled ``demo_data/outcrop.laz`` byte for byte;
``generate board`` ray-casts the 2012 paper's board at rotation (alpha, beta).
"""

from __future__ import annotations

import argparse

from rough_viewer.io.output import check_output_path, write_path_atomic
from rough_viewer.vocabulary import InputError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="list the demo data sets or write one to a LAS/LAZ file",
        description="Demo data: a synthetic basalt outcrop with ground truth (bundled) and "
        "the 2012 paper's hemisphere board (generated for any rotation).",
    )
    p.add_argument("--list", action="store_true", help="list the demos (the default)")
    demo_sub = p.add_subparsers(dest="demo_command", metavar="ACTION")
    g = demo_sub.add_parser(
        "generate",
        help="generate a demo and write it as LAS/LAZ with its truth labels",
        description="Generate a demo and write it as .las or .laz, with the ground truth as "
        "the extra dimension 'truth' (and 'face' for the outcrops).",
    )
    g.add_argument("name", help="demo name (see `rough-viewer demo --list`)")
    g.add_argument("--out", required=True, metavar="FILE.laz", help="output .laz or .las")
    g.add_argument("--alpha", type=float, default=0.0, metavar="DEG",
                   help="board only: rotation about the vertical axis, degrees (default 0)")
    g.add_argument("--beta", type=float, default=0.0, metavar="DEG",
                   help="board only: rotation about the board's horizontal axis, degrees "
                   "(default 0)")
    g.add_argument("--force", action="store_true", help="overwrite an existing output")
    p.set_defaults(func=run)


def _list() -> int:
    from rough_viewer.synthetic.demos import list_demos

    demos = list_demos()
    width = max(len(d.name) for d in demos)
    for d in demos:
        where = str(d.path) if d.path is not None else "(generated on the fly)"
        print(f"{d.name:<{width}}  {d.description}")
        print(f"{'':<{width}}  {where}")
    return 0


def run(args: argparse.Namespace) -> int:
    if getattr(args, "demo_command", None) != "generate":
        return _list()
    from rough_viewer.synthetic.demos import list_demos, write_demo

    names = [d.name for d in list_demos()]
    if args.name not in names:
        raise InputError(f"unknown demo {args.name!r}; choose one of: {', '.join(names)}")
    out = check_output_path(args.out, force=args.force)
    if out.suffix.lower() not in (".las", ".laz"):
        raise InputError(f"demo output must be .las or .laz: {out}")
    for opt, val in (("--alpha", args.alpha), ("--beta", args.beta)):
        if not -90.0 < val < 90.0:
            raise InputError(f"{opt} must be between -90 and 90 degrees, got {val:g}")
    written: list[int] = []
    write_path_atomic(out, lambda tmp: written.append(
        write_demo(args.name, tmp, alpha_deg=args.alpha, beta_deg=args.beta)))
    print(f"wrote {written[0]} points to {out}")
    return 0
