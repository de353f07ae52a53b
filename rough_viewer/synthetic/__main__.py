"""``python -m rough_viewer.synthetic [OUT_DIR]``: rewrite the bundled demo files.

Writes ``outcrop.laz`` and ``outcrop-small.laz`` into OUT_DIR (default the
repository's ``demo_data/``); the same code always writes the same bytes.
"""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    from rough_viewer.synthetic.demos import regenerate_bundled

    args = sys.argv[1:] if argv is None else argv
    for path in regenerate_bundled(args[0] if args else None):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
