"""``rough-viewer lesson``: list, check and print the lessons (docs/lessons.md).

Contract::

    rough-viewer lesson --list
    rough-viewer lesson NAME|FILE.toml [--handout OUT.html] [--force]

``NAME`` is a bundled lesson (``tilted-board``, ``turned-wall``, ``scale``) or a
lesson file. Without ``--handout`` the lesson is read and checked, and its steps
listed (a teacher's check of a file of their own: a problem is one line naming the
file and the field, exit status 2). ``--handout OUT.html`` writes its printable
handout with blank answer lines (the app's Lesson tab downloads one with a
student's answers and figures); an existing file is kept unless ``--force``.
``rough-viewer serve --lesson NAME`` opens the app on it.
"""

from __future__ import annotations

import argparse

from rough_viewer.vocabulary import InputError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "lesson",
        help="list, check or print a lesson's handout",
        description="Guided lessons of the app (docs/lessons.md): list the bundled ones, "
        "check a lesson file, or write a printable handout.",
    )
    p.add_argument("name", nargs="?", metavar="NAME",
                   help="a bundled lesson or a lesson file (.toml)")
    p.add_argument("--list", action="store_true", help="list the bundled lessons")
    p.add_argument("--handout", metavar="OUT.html",
                   help="write the lesson's printable handout (blank answers)")
    p.add_argument("--force", action="store_true", help="overwrite an existing --handout file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rough_viewer.lessons import bundled_names, find_lesson

    if args.list or not args.name:
        if args.handout:
            raise InputError("--handout needs a lesson NAME")
        for name in bundled_names():
            print(f"{name:<14}  {find_lesson(name).title}")
        return 0
    out = None
    if args.handout:
        from rough_viewer.io.output import check_output_path

        out = check_output_path(args.handout, force=args.force)
        if out.suffix.lower() not in (".html", ".htm"):
            raise InputError(f"--handout must be an .html file: {args.handout}")
    lesson = find_lesson(args.name)
    if out is None:
        print(f"{lesson.name}: {lesson.title} ({len(lesson.steps)} steps)")
        for k, step in enumerate(lesson.steps):
            q = step.question
            print(f"  {k + 1}. {step.title}" + (f" [{q.measure}]" if q is not None else ""))
        return 0
    from rough_viewer.io.output import write_atomic
    from rough_viewer.lessons.handout import handout_html

    text = handout_html(lesson)
    write_atomic(out, lambda fh: fh.write(text))
    print(f"rough-viewer: wrote {out} ({len(lesson.steps)} steps)")
    return 0
