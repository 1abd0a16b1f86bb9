"""A report's self-contained HTML twin: ``report.html`` beside ``report.md``.

One file, readable when mailed: the Markdown the report already writes is converted here
(a small converter for what the reports use: headings, paragraphs, bullet lists, bold,
inline code, fenced code, pipe tables, images), every figure the Markdown links is embedded
as a ``data:`` URI (base64), the style is inline, nothing is fetched from a network.
"""

from __future__ import annotations

import base64
import html
import os
import re
from pathlib import Path

__all__ = ["markdown_to_html", "write_html"]

_MIME = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".svg": "image/svg+xml",
         ".gif": "image/gif"}

_STYLE = """
body{font-family:-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;max-width:1100px;margin:2em auto;
padding:0 1.2em;line-height:1.45;color:#1b1b1b}
h1{font-size:1.6em;border-bottom:2px solid #ccc;padding-bottom:.2em}
h2{font-size:1.3em;border-bottom:1px solid #ddd;margin-top:1.6em}
h3{font-size:1.1em}
code{background:#f3f3f3;padding:0 .2em;border-radius:3px;font-size:.92em}
pre{background:#f6f6f6;padding:.7em;overflow-x:auto;font-size:.82em;line-height:1.3;border:1px solid #e3e3e3}
pre code{background:none;padding:0}
img{max-width:100%;height:auto;display:block;margin:.6em 0;border:1px solid #eee}
table{border-collapse:collapse;margin:.6em 0;font-size:.9em}
td,th{border:1px solid #ccc;padding:.2em .5em;text-align:left}
th{background:#f0f0f0}
section#findings{background:#f7fbff;border:1px solid #c9ddf0;border-radius:6px;padding:.2em 1em 1em}
"""


def _inline(text: str, base: Path | None) -> str:
    """Escape, then inline code (kept verbatim), images, links and bold (which may hold code)."""
    codes: list[str] = []

    def keep(m):
        codes.append(f"<code>{html.escape(m.group(1))}</code>")
        return f"\x00{len(codes) - 1}\x00"

    p = re.sub(r"`([^`]+)`", keep, text)
    p = html.escape(p, quote=False)
    p = re.sub(r"!\[([^\]]*)\]\(([^)\s]+)\)", lambda m: _img(m.group(1), m.group(2), base), p)
    p = re.sub(r"\[([^\]]+)\]\(([^)\s]+)\)", r'<a href="\2">\1</a>', p)
    p = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", p)
    return re.sub("\x00(\\d+)\x00", lambda m: codes[int(m.group(1))], p)


def _img(alt: str, src: str, base: Path | None) -> str:
    data = None
    path = Path(src) if base is None else base / src
    if not src.startswith(("http:", "https:", "data:")) and path.is_file():
        mime = _MIME.get(path.suffix.lower(), "application/octet-stream")
        data = f"data:{mime};base64,{base64.b64encode(path.read_bytes()).decode('ascii')}"
    if data is None:  # never a network fetch: a figure that is not here is said to be missing
        return f"<em>[figure {html.escape(alt)} not available]</em>"
    return f'<figure><img alt="{html.escape(alt)}" src="{data}"><figcaption>{html.escape(alt)}</figcaption></figure>'


def markdown_to_html(md: str, *, base: Path | None = None) -> str:
    """The body HTML of the Markdown subset the reports write; images under ``base`` embedded.
    The section titled "Findings" is wrapped in ``<section id="findings">``."""
    lines = md.splitlines()
    out: list[str] = []
    i = 0
    para: list[str] = []
    in_list = False
    open_findings = False

    def flush():
        nonlocal para
        if para:
            out.append(f"<p>{_inline(' '.join(para), base)}</p>")
            para = []

    def close_list():
        nonlocal in_list
        if in_list:
            out.append("</ul>")
            in_list = False

    while i < len(lines):
        line = lines[i]
        if line.startswith("```"):
            flush(); close_list()
            j = i + 1
            while j < len(lines) and not lines[j].startswith("```"):
                j += 1
            out.append("<pre><code>" + html.escape("\n".join(lines[i + 1:j])) + "</code></pre>")
            i = j + 1
            continue
        m = re.match(r"^(#{1,6})\s+(.*)$", line)
        if m:
            flush(); close_list()
            level = len(m.group(1))
            if level <= 2 and open_findings:
                out.append("</section>")
                open_findings = False
            if level == 2 and m.group(2).strip().lower() == "findings":
                out.append('<section id="findings">')
                open_findings = True
            out.append(f"<h{level}>{_inline(m.group(2), base)}</h{level}>")
            i += 1
            continue
        if line.lstrip().startswith("|") and i + 1 < len(lines) and re.match(r"^\s*\|[\s:|-]+\|\s*$", lines[i + 1]):
            flush(); close_list()
            head = [c.strip() for c in line.strip().strip("|").split("|")]
            rows = []
            j = i + 2
            while j < len(lines) and lines[j].lstrip().startswith("|"):
                rows.append([c.strip() for c in lines[j].strip().strip("|").split("|")])
                j += 1
            out.append("<table><tr>" + "".join(f"<th>{_inline(c, base)}</th>" for c in head) + "</tr>"
                       + "".join("<tr>" + "".join(f"<td>{_inline(c, base)}</td>" for c in r) + "</tr>" for r in rows)
                       + "</table>")
            i = j
            continue
        m = re.match(r"^\s*[*-]\s+(.*)$", line)
        if m:
            flush()
            if not in_list:
                out.append("<ul>")
                in_list = True
            item = [m.group(1)]
            j = i + 1
            while j < len(lines) and lines[j].startswith("  ") and lines[j].strip() and \
                    not re.match(r"^\s*[*-]\s+", lines[j]):
                item.append(lines[j].strip())
                j += 1
            out.append(f"<li>{_inline(' '.join(item), base)}</li>")
            i = j
            continue
        if not line.strip():
            flush(); close_list()
            i += 1
            continue
        close_list()
        para.append(line.strip())
        i += 1
    flush(); close_list()
    if open_findings:
        out.append("</section>")
    return "\n".join(out)


def write_html(md_path: str | os.PathLike, html_path: str | os.PathLike | None = None, *,
               title: str | None = None) -> Path:
    """``report.html`` from ``report.md`` (figures resolved beside it and embedded)."""
    md_path = Path(md_path)
    html_path = Path(html_path) if html_path is not None else md_path.with_suffix(".html")
    md = md_path.read_text()
    if title is None:
        m = re.search(r"^#\s+(.*)$", md, flags=re.M)
        title = m.group(1) if m else md_path.stem
    body = markdown_to_html(md, base=md_path.parent)
    page = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head>\n<body>\n{body}\n</body></html>\n")
    html_path.write_text(page, encoding="utf-8")
    return html_path
