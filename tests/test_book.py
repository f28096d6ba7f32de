"""The book's build (mkdocs.yml, docs/hooks.py), without MkDocs: CI builds the site itself with
`mkdocs build --strict` (.ci/run). Here: the hooks give GitHub's anchors, so a page's links work
on GitHub and in the site alike; a link out of docs/ to a file that is not there is reported
(which --strict makes a failure) and one to a file that is points at it; and the navigation
lists every page."""

import importlib.util
import logging
from pathlib import Path
from types import SimpleNamespace

import yaml
from test_docs import HEADING, prose_lines, slug

ROOT = Path(__file__).resolve().parent.parent
_spec = importlib.util.spec_from_file_location("book_hooks", ROOT / "docs" / "hooks.py")
hooks = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(hooks)


def test_every_heading_gets_githubs_anchor():
    headings = [
        HEADING.match(line)[2].replace("`", "").replace("*", "")
        for page in ROOT.glob("docs/**/*.md")
        for _, line in prose_lines(page.read_text(), spans=True)
        if HEADING.match(line) and "](" not in line
    ]
    assert len(headings) > 100
    assert [hooks.github_slug(h) for h in headings] == [slug(h) for h in headings]
    # where Python-Markdown's own slug differs from GitHub's: runs of separators are kept
    assert hooks.github_slug("CPU / GPU: 2 -- 4") == "cpu--gpu-2----4"


def _config(tmp_path, repo_url=None):
    (tmp_path / "docs" / "how").mkdir(parents=True)
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "there.py").write_text("")
    return SimpleNamespace(
        docs_dir=str(tmp_path / "docs"), site_dir=str(tmp_path / "site"), repo_url=repo_url, mdx_configs={}
    )


def _page(tmp_path, uri="how/page.md"):
    return SimpleNamespace(
        file=SimpleNamespace(src_uri=uri, abs_src_path=str(tmp_path / "docs" / uri), dest_uri=uri[:-3] + ".html")
    )


def test_a_link_out_of_docs_is_checked_and_pointed_at_the_file(tmp_path, caplog):
    config, page = _config(tmp_path), _page(tmp_path)
    text = (
        "[in](../other.md#a) [out](../../src/there.py#L3) [web](https://x.org/y)\n"
        "```\n[fenced](../../src/gone.py)\n```\n"
        "[gone](../../src/gone.py)\n"
    )
    with caplog.at_level(logging.WARNING, logger="mkdocs.plugins.raybench"):
        out = hooks.on_page_markdown(text, page, config, None)
    assert out.splitlines() == [
        "[in](../other.md#a) [out](repo:src/there.py#L3) [web](https://x.org/y)",
        "```",
        "[fenced](../../src/gone.py)",
        "```",
        "[gone](../../src/gone.py)",
    ]
    assert [r.getMessage() for r in caplog.records] == [
        "how/page.md:5 links to ../../src/gone.py, which is not in the repository"
    ]
    html = '<a href="repo:src/there.py#L3">out</a>'
    assert hooks.on_page_content(html, page, config, None) == '<a href="../../src/there.py#L3">out</a>'
    hosted = _config(tmp_path / "h", repo_url="https://example.org/raybench/")
    assert (
        hooks.on_page_content(html, _page(tmp_path / "h"), hosted, None)
        == '<a href="https://example.org/raybench/blob/main/src/there.py#L3">out</a>'
    )


def test_the_navigation_lists_every_page_once():
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())

    def pages(node):
        if isinstance(node, str):
            yield node
        elif isinstance(node, list):
            for item in node:
                yield from pages(item)
        elif isinstance(node, dict):
            for value in node.values():
                yield from pages(value)

    listed = list(pages(config["nav"]))
    on_disk = sorted(p.relative_to(ROOT / "docs").as_posix() for p in ROOT.glob("docs/**/*.md"))
    assert sorted(listed) == on_disk
    assert config["docs_dir"] == "docs" and "docs/hooks.py" in config["hooks"]
