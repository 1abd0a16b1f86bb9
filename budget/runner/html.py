"""A report's self-contained HTML twin: ``report.html`` beside ``report.md``.

One file, readable when mailed: the Markdown the report already writes is converted by
Python-Markdown (its ``tables`` and ``fenced_code`` extensions; raw HTML in the Markdown is
shown as text, never passed through), every figure the Markdown links is embedded as a
``data:`` URI (base64), the style is inline, nothing is fetched from a network.
"""

from __future__ import annotations

import base64
import html
import os
import re
import xml.etree.ElementTree as etree
from pathlib import Path

import markdown
from markdown.treeprocessors import Treeprocessor

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
details{margin:1.2em 0;border:1px solid #ddd;border-radius:4px;padding:.3em .8em}
summary{cursor:pointer;font-weight:600}
"""


def _figure(img: etree.Element, base: Path | None) -> etree.Element:
    """The ``<figure>`` of one Markdown image, its file embedded; a figure that is not a local
    file (a network address, or missing) is said to be missing, never fetched."""
    alt, src = img.get("alt", ""), img.get("src", "")
    path = Path(src) if base is None else base / src
    if src.startswith(("http:", "https:", "data:")) or not path.is_file():
        missing = etree.Element("em")
        missing.text = f"[figure {alt} not available]"
        return missing
    mime = _MIME.get(path.suffix.lower(), "application/octet-stream")
    fig = etree.Element("figure")
    etree.SubElement(fig, "img", alt=alt,
                     src=f"data:{mime};base64,{base64.b64encode(path.read_bytes()).decode('ascii')}")
    etree.SubElement(fig, "figcaption").text = alt
    return fig


#: sections folded away (``<details>``): h2 title -> the summary line shown
FOLDED = {"scenario": "Scenario (the resolved TOML: click to show)"}


class _ReportPage(Treeprocessor):
    """Embeds the figures (:func:`_figure`; an image alone in its paragraph replaces the
    paragraph), wraps the section titled "Findings" (to the next h1 or h2) in
    ``<section id="findings">`` and folds each section of :data:`FOLDED` into ``<details>``."""

    def __init__(self, md, base: Path | None):
        super().__init__(md)
        self.base = base

    def run(self, root: etree.Element) -> None:
        for parent in list(root.iter()):
            for i, child in enumerate(list(parent)):
                if child.tag != "img":
                    continue
                new = _figure(child, self.base)
                new.tail = child.tail
                parent.remove(child)
                parent.insert(i, new)
        for i, p in enumerate(list(root)):
            if (p.tag == "p" and len(p) == 1 and p[0].tag == "figure" and not (p.text or "").strip()
                    and not (p[0].tail or "").strip()):
                root.remove(p)
                p[0].tail = p.tail
                root.insert(i, p[0])
        section = None
        for child in list(root):
            if child.tag in ("h1", "h2"):
                section = None
                title = "".join(child.itertext()).strip().lower()
                if child.tag == "h2" and title == "findings":
                    section = etree.Element("section", id="findings")
                elif child.tag == "h2" and title in FOLDED:
                    section = etree.Element("details")
                    etree.SubElement(section, "summary").text = FOLDED[title]
                    root.insert(list(root).index(child), section)
                    section.tail = "\n"
                    root.remove(child)  # the summary replaces the heading
                    continue
                if section is not None and section.tag == "section":
                    section.text, section.tail = "\n", "\n"
                    root.insert(list(root).index(child), section)
            if section is not None:
                root.remove(child)
                section.append(child)


def markdown_to_html(md: str, *, base: Path | None = None) -> str:
    """The body HTML of a report's Markdown; images under ``base`` embedded. The section
    titled "Findings" is wrapped in ``<section id="findings">``, the "Scenario" folded away."""
    conv = markdown.Markdown(extensions=["tables", "fenced_code"], output_format="html")
    conv.preprocessors.deregister("html_block")  # raw HTML is text in a report, never markup
    conv.inlinePatterns.deregister("html")
    # after "unescape" (priority 0), which restores the escaped characters of the alt texts
    conv.treeprocessors.register(_ReportPage(conv, base), "report_page", -1)
    return conv.convert(md)


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
