"""MkDocs hooks for raybench's book (mkdocs.yml names this file; it is not a page).

The pages are written to read on GitHub as well as in the built site, so two things are
GitHub's:

- A heading's anchor is GitHub's slug (tests/test_docs.py's ``slug``): the pages, the README
  and comments in the source cite ``docs/page.md#anchor`` with it.
- A link may leave docs/ for a file of the repository (a results file, a module). MkDocs would
  call it missing; here it is checked to exist (a missing one fails ``mkdocs build --strict``)
  and pointed at that file: in the repository at ``repo_url`` when mkdocs.yml sets one, else
  at the checkout beside the built site (so ``site/`` opened from a clone follows it).
"""

from __future__ import annotations

import logging
import os
import re
from pathlib import Path

log = logging.getLogger("mkdocs.plugins.raybench")

REPO = "repo:"  # a placeholder scheme between the two hooks, which MkDocs's checks leave alone
LINK = re.compile(r"(\]\(\s*<?)([^)\s>#:]+)((?:#[^)\s>]*)?)")
FENCE = re.compile(r"^\s*(```|~~~)")


def github_slug(value: str, separator: str = "-") -> str:
    """GitHub's anchor for a heading's text: lowercased, every character but letters, digits,
    '_', '-' and spaces dropped, each space a hyphen (runs of them are not merged)."""
    return re.sub(r"[^\w\- ]", "", value.strip().lower()).replace(" ", separator)


def on_config(config):
    config.mdx_configs.setdefault("toc", {})["slugify"] = github_slug
    return config


def on_page_markdown(markdown, page, config, files):
    docs = Path(config.docs_dir).resolve()
    root = docs.parent
    here = Path(page.file.abs_src_path).parent
    out, fenced = [], False
    for number, line in enumerate(markdown.splitlines(keepends=True), 1):
        if FENCE.match(line):
            fenced = not fenced
        if not fenced and not line.startswith("    "):

            def outside(m, number=number):
                target = (here / m.group(2)).resolve()
                if target.is_relative_to(docs) or not target.is_relative_to(root):
                    return m.group(0)
                if not target.exists():
                    where = f"{page.file.src_uri}:{number}"
                    log.warning("%s links to %s, which is not in the repository", where, m.group(2))
                    return m.group(0)
                return f"{m.group(1)}{REPO}{target.relative_to(root).as_posix()}{m.group(3)}"

            line = LINK.sub(outside, line)
        out.append(line)
    return "".join(out)


def on_page_content(html, page, config, files):
    root = Path(config.docs_dir).resolve().parent
    repo_url = (config.repo_url or "").rstrip("/")
    page_dir = (Path(config.site_dir).resolve() / page.file.dest_uri).parent

    def point(m):
        path = m.group(1)
        if repo_url:
            return f'href="{repo_url}/blob/main/{path}'
        return 'href="' + os.path.relpath(root / path, page_dir).replace(os.sep, "/")

    return re.sub(rf'href="{REPO}([^"#]*)', point, html)
