"""The docs as a reader meets them. Every relative link in the Markdown pages names a file that
exists, and every #anchor a heading of the page it points to (GitHub's slugs); comments and
docstrings that cite a page as ``docs/page.md`` or ``docs/page.md#anchor`` are held to the same.
The README opens with the two commands, and its Python example runs as written.

Plain text only, no Markdown library: the pages are read once, a few hundred KB in all."""

import re
from functools import cache
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent

# The pages whose links are checked: the docs, the READMEs a reader starts from, and the results'.
PAGES = sorted(
    {
        *ROOT.glob("docs/**/*.md"),
        ROOT / "README.md",
        *ROOT.glob("benchmarks/**/README.md"),
        ROOT / "experiments" / "README.md",
    }
)

LINK = re.compile(r"!?\[((?:[^\[\]]|\[[^\]]*\])*)\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
CODE_SPAN = re.compile(r"(`+)(?:(?!\1).)+?\1")
FENCE = re.compile(r"^\s*(```|~~~)")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
# A page cited in source text: docs/name.md, optionally with its #anchor.
CITED = re.compile(r"docs/([\w./-]+\.md)(#[\w-]+)?")
SOURCE_SUFFIXES = {".py", ".sh", ".md", ".wgsl", ".toml"}


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: its text as rendered (links to their text, no code or
    emphasis marks), lowercased, every character but letters, digits, '_', '-' and spaces
    dropped, spaces to hyphens."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    text = text.replace("`", "").replace("*", "")
    text = re.sub(r"[^\w\- ]", "", text.strip().lower())
    return text.replace(" ", "-")


def prose_lines(text: str, spans: bool = False):
    """(line number, line) outside fenced and indented code blocks; inline code spans blanked
    unless ``spans``."""
    fenced = False
    for number, line in enumerate(text.splitlines(), 1):
        if FENCE.match(line):
            fenced = not fenced
            continue
        if not fenced and not line.startswith("    "):
            yield number, line if spans else CODE_SPAN.sub("", line)


@cache
def anchors(page: Path) -> frozenset:
    """The anchors GitHub gives a page's headings: a repeated heading's second is slug-1."""
    seen: dict[str, int] = {}
    for _, line in prose_lines(page.read_text(), spans=True):
        m = HEADING.match(line)
        if m:
            s = slug(m.group(2))
            n = seen.get(s, 0)
            seen[s] = n + 1
            if n:
                seen.setdefault(f"{s}-{n}", 1)
    return frozenset(seen)


def broken_links(page: Path) -> list[str]:
    """Each relative link of the page whose file is missing or whose anchor is not a heading."""
    broken = []
    for number, line in prose_lines(page.read_text()):
        for m in LINK.finditer(line):
            target = m.group(2)
            if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto:
                continue
            path, _, anchor = target.partition("#")
            dest = (page.parent / path).resolve() if path else page
            where = f"{page.relative_to(ROOT) if page.is_relative_to(ROOT) else page.name}:{number}: {target}"
            if not dest.exists():
                broken.append(f"{where} (no such file)")
            elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
                broken.append(f"{where} (no heading #{anchor} in {dest.name})")
    return broken


def test_slugs_are_githubs():
    assert slug("Whitted shading (issue 14): secondary rays") == "whitted-shading-issue-14-secondary-rays"
    assert slug("The wgpu frame's readback (lease x1 and x4)") == "the-wgpu-frames-readback-lease-x1-and-x4"
    assert slug("`Camera.basis` and **NumPy**") == "camerabasis-and-numpy"
    assert slug("A [link](x.md) in it") == "a-link-in-it"


def test_a_repeated_heading_gets_a_number(tmp_path):
    page = tmp_path / "p.md"
    page.write_text("# T\n## The floor\n## The floor\n```\n## Not a heading\n```\n## The `floor`\n")
    assert anchors(page) == {"t", "the-floor", "the-floor-1", "the-floor-2"}


def test_a_broken_link_is_found(tmp_path):
    (tmp_path / "there.md").write_text("# There\n\n## A section\n")
    page = tmp_path / "p.md"
    page.write_text(
        "# P\n[ok](there.md#a-section) [ok](#p) [web](https://example.com/x#y) `[code](gone.md)`\n"
        "[gone](gone.md) [no anchor](there.md#b-section) [self](#q)\n"
    )
    found = broken_links(page)
    assert [f.split(": ", 1)[1] for f in found] == [
        "gone.md (no such file)",
        "there.md#b-section (no heading #b-section in there.md)",
        "#q (no heading #q in p.md)",
    ]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_links_resolve(page):
    assert broken_links(page) == []


def test_pages_cited_in_source_exist():
    """A comment, docstring or script that names docs/page.md#anchor names a page that exists,
    and a heading of it."""
    missing = []
    for folder in ("src", "benchmarks", "tests", "experiments"):
        for path in (ROOT / folder).rglob("*"):
            if path.suffix not in SOURCE_SUFFIXES or not path.is_file() or path == Path(__file__):
                continue
            for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                for m in CITED.finditer(line):
                    page = ROOT / "docs" / m.group(1)
                    anchor = (m.group(2) or "#")[1:]
                    if not page.exists() or (anchor and anchor not in anchors(page)):
                        missing.append(f"{path.relative_to(ROOT)}:{number}: {m.group(0)}")
    assert missing == []


def test_readme_opens_with_the_two_commands():
    text = (ROOT / "README.md").read_text()
    first = re.search(r"^```(\w*)\n(.*?)^```", text, flags=re.S | re.M)
    assert text.startswith("# raybench\n\n```bash\n") and first[1] == "bash"
    assert [line.split()[0] for line in first[2].splitlines()] == ["./run.sh", "./test.sh"]


def test_readme_python_example_runs_as_written(tmp_path, monkeypatch):
    example = re.search(r"^```python\n(.*?)^```", (ROOT / "README.md").read_text(), flags=re.S | re.M)[1]
    assert len(example.splitlines()) <= 10
    monkeypatch.chdir(tmp_path)  # it writes spheres.png where it runs
    namespace: dict = {}
    exec(compile(example, "README.md", "exec"), namespace)
    frame = namespace["frame"]
    assert frame.image.shape == (1050, 1680, 3) and frame.hits.shape == (1050, 1680)
    assert (tmp_path / "spheres.png").is_file() and (frame.hits >= 0).any() and (frame.hits == -1).any()
    assert np.unique(frame.hits).size > 100  # a picture of many spheres, not a blank frame


@pytest.mark.parametrize("page", sorted(ROOT.glob("docs/**/*.md")), ids=lambda p: str(p.relative_to(ROOT)))
def test_a_page_is_short_and_its_headings_name_no_lease(page):
    """A book's page is read in one sitting (800 lines at most); a heading names what was done,
    never the machine lease it was done on (the notes' text may)."""
    text = page.read_text()
    assert len(text.splitlines()) <= 800
    leases = [
        line for _, line in prose_lines(text, spans=True) if HEADING.match(line) and re.search(r"\bleases?\b", line)
    ]
    assert leases == []
