"""Text that reaches the browser: escaping for viser Markdown, and error messages
that are safe to show.

viser renders Markdown with raw HTML enabled, so any string a user typed or a file
supplied (paths, file names, error messages, CRS text) would otherwise run as HTML
in every open tab. :func:`md` turns such a string into Markdown that renders as the
same characters and nothing else. Every Markdown builder of the app passes
untrusted text through it; trusted text (our own labels and numbers) is written
as Markdown directly.

:func:`public_message` makes an error message fit to show to a client: it never
carries the server's own paths (temp files, the data folder) or text read from a
file (a reader's "could not convert string 'admin'" echoes file content).

>>> print(md("<img src=x onerror=alert(1)>"))
&lt;img src=x onerror=alert\\(1\\)&gt;
>>> public_message("cannot parse /tmp/up-1.xyz: could not convert 'admin'",
...                paths={"/tmp/up-1.xyz": "points.xyz"}, quoted=False)
"cannot parse points.xyz: could not convert '…'"
"""

from __future__ import annotations

import re
from collections.abc import Mapping

from rough_viewer.app.limits import MAX_MESSAGE

_MD_PUNCT = re.compile(r"([\\`*_{}\[\]()#+!|~])")
_BLOCK_START = re.compile(r"^(\s*\d*)([-+=.)])")
_QUOTED = re.compile(r"'[^'\n]*'|\"[^\"\n]*\"|b'[^'\n]*'")
_ABS_PATH = re.compile(r"(?<![\w.])(?:[A-Za-z]:)?[/\\](?:[^\s/\\:'\"]+[/\\])*[^\s/\\:'\",;]*")


def md(text: object, *, max_chars: int | None = None) -> str:
    """``text`` as Markdown that renders as exactly those characters.

    HTML special characters become entities (so no tag or attribute survives),
    the punctuation that starts Markdown inline syntax is backslash-escaped (no
    emphasis, code, link, image, table cell or heading), a leading list, quote or
    rule marker is escaped, and line breaks become spaces (no new block).

    Parameters
    ----------
    text
        Any value; ``str(text)`` is escaped.
    max_chars
        Cut the text (before escaping) to this many characters, ending in "…".
    """
    s = str(text)
    if max_chars is not None and len(s) > max_chars:
        s = s[: max(0, max_chars - 1)] + "…"
    s = "".join(ch if ch.isprintable() else " " for ch in s)
    s = _MD_PUNCT.sub(r"\\\1", s)
    s = _BLOCK_START.sub(r"\1\\\2", s, count=1)  # a list or rule marker; ">" is an entity
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def public_message(
    text: str,
    *,
    paths: Mapping[str, str] | None = None,
    quoted: bool = True,
) -> str:
    """An error message fit to show to a client.

    Parameters
    ----------
    text
        The message (only its first line is kept).
    paths
        Server paths -> what the client may see instead (e.g. an upload's temp
        file -> the file name the user gave). Any other absolute path left in
        the message is replaced by "…".
    quoted
        Keep quoted fragments. With False, every ``'...'`` or ``"..."`` is
        replaced by ``'…'``: readers quote the text they could not parse, which
        is the file's content.
    """
    s = text.splitlines()[0] if text else ""
    marks: dict[str, str] = {}
    for k, (path, shown) in enumerate(sorted((paths or {}).items(), key=lambda kv: -len(kv[0]))):
        if path:
            mark = f"\x00{k}\x00"
            s = s.replace(path, mark)
            marks[mark] = shown
    if not quoted:
        s = _QUOTED.sub("'…'", s)
    s = _ABS_PATH.sub("…", s)
    for mark, shown in marks.items():
        s = s.replace(mark, shown)
    if len(s) > MAX_MESSAGE:
        s = s[: MAX_MESSAGE - 1] + "…"
    return s
