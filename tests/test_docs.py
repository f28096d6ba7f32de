"""The READMEs as a newcomer meets them: the two commands first, every
relative link and image pointing at a file that exists, and the Python
example running as written."""

import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ["README.md", "benchmarks/README.md", "experiments/README.md"]
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def prose(text: str) -> str:
    """The text outside fenced code blocks, where a link is a link."""
    return re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)


def anchors(text: str) -> set[str]:
    """GitHub's anchors for the headings: lower case, punctuation dropped, spaces to hyphens."""
    heads = re.findall(r"^#+ (.+)$", prose(text), flags=re.M)
    return {re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-") for h in heads}


def links(doc: str) -> list[str]:
    return [t for t in LINK.findall(prose((ROOT / doc).read_text())) if not re.match(r"[a-z]+:", t)]


@pytest.mark.parametrize("doc", DOCS)
def test_every_relative_link_resolves(doc):
    found = links(doc)
    broken = []
    for target in found:
        path, _, anchor = target.partition("#")
        file = (ROOT / doc).parent / path if path else ROOT / doc
        if not file.exists():
            broken.append(target)
        elif anchor and file.suffix == ".md" and anchor not in anchors(file.read_text()):
            broken.append(target)
    assert not broken, f"{doc}: links to nothing: {broken}"


def test_the_link_check_sees_links_and_broken_ones(tmp_path):
    """The check itself: it finds links and images, skips code and URLs, and a missing file is broken."""
    text = "[a](README.md) ![b](docs/x.png) [c](https://e/x) [d](#raybench)\n```\n[e](nothing)\n```\n"
    assert LINK.findall(prose(text)) == ["README.md", "docs/x.png", "https://e/x", "#raybench"]
    assert "raybench" in anchors((ROOT / "README.md").read_text())
    assert not (ROOT / "docs/x.png").exists()


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
