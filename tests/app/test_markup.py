"""Escaping for viser Markdown and safe error messages, checked against the same
Markdown parser family viser's client uses (CommonMark + GFM, raw HTML on).

The rendered HTML is produced with ``markdown-it-py`` (CommonMark, HTML enabled,
GFM tables and strikethrough), so a string that renders as plain text there
renders as plain text in viser's react-markdown + rehype-raw too.
"""

from __future__ import annotations

import html

import pytest

from rough_viewer.app.markup import md, public_message

markdown_it = pytest.importorskip("markdown_it")

HOSTILE = [
    '<iframe srcdoc="<script>parent.x=1</script>">',
    "<img src=x onerror=alert(1)>.las",
    "[click](javascript:alert(1)).xyz",
    "![x](http://evil.example/x.png)",
    "**bold** _it_ `code` ~~gone~~ | cell |",
    "# heading",
    "- item",
    "1. first",
    "> quote",
    "&lt;script&gt; &amp; &#60;b&#62;",
    "a\nb\r\n<script>",
    "C:\\data\\scan (1).laz",
    "\\*escaped\\*",
]


def render(text: str) -> str:
    return markdown_it.MarkdownIt("commonmark", {"html": True}).enable(
        ["table", "strikethrough"]).renderInline(text)


@pytest.mark.parametrize("text", HOSTILE)
def test_hostile_text_renders_as_itself(text):
    out = render(md(text))
    # no element at all: every < in the output is an escaped one
    assert "<" not in out.replace("&lt;", "")
    # and it reads back as the original characters (line breaks become spaces)
    assert " ".join(html.unescape(out).split()) == " ".join(text.split())


def test_cut_to_length():
    assert md("x" * 500, max_chars=10) == "x" * 9 + "…"


def test_public_message_hides_paths_and_file_content():
    msg = ("cannot parse /tmp/rough-viewer-uploads-abc/upload-3.xyz as x y z columns: "
           "could not convert string 'admin' to float: 'admin'")
    out = public_message(msg, paths={"/tmp/rough-viewer-uploads-abc/upload-3.xyz": "pts.xyz"},
                         quoted=False)
    assert out == "cannot parse pts.xyz as x y z columns: could not convert string '…' to " \
                  "float: '…'"
    assert public_message("file not found: /srv/secret/data.las") == "file not found: …"
    assert len(public_message("y" * 1000)) == 300
    assert public_message("first line\nsecond line") == "first line"
