"""The README is the front page and the docs/ pages hold the rest: the README stays short, its table of
contents and command table are whole, its quick start is what CI runs, its diagnosis is the tool's own
output, and every relative link in the README and docs/*.md reaches a file (and a heading, where it
names one)."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
DOCS = ROOT / "docs"
PAGES = [README, *sorted(DOCS.glob("*.md"))]
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def unfenced(text: str) -> str:
    """The text without fenced code blocks (a `# plant.toml` inside one is no heading)."""
    return re.sub(r"^```.*?^```[^\n]*$", "", text, flags=re.M | re.S)


def prose(text: str) -> str:
    """The text without code: fenced blocks and inline code (a link in either is no link)."""
    return re.sub(r"`[^`\n]*`", "", unfenced(text))


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading.strip())  # a link in a heading: its text
    return re.sub(r"[^\w\- ]", "", text.lower()).replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Every heading's anchor in a Markdown file, GitHub's -1, -2 ... on repeats."""
    text = unfenced(path.read_text(encoding="utf-8"))
    seen: dict[str, int] = {}
    out = set()
    for heading in re.findall(r"^#{1,6} +(.+?) *#*$", text, re.M):
        base = slug(heading)
        n = seen.get(base, 0)
        seen[base] = n + 1
        out.add(base if n == 0 else f"{base}-{n}")
    return out


def section(text: str, title: str) -> str:
    """A `## title` section of a Markdown text, up to the next `## ` heading."""
    start = text.index(f"\n## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:end if end >= 0 else len(text)]


def cli_commands() -> list[str]:
    """The commands `sniffer --help` lists, from the parser itself."""
    import argparse

    from sniffer.cli import build_parser

    (sub,) = [a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)]
    return [a.dest for a in sub._choices_actions] or list(sub.choices)


def test_the_readme_is_a_front_page():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines: move detail to a page in docs/"


def test_the_table_of_contents_names_every_section_and_reaches_it():
    text = README.read_text(encoding="utf-8")
    toc = section(text, "Contents")
    targets = re.findall(r"^- \[[^\]]+\]\(#([^)]+)\)$", toc, re.M)
    sections = [slug(h) for h in re.findall(r"^## +(.+)$", unfenced(text), re.M) if h != "Contents"]
    assert targets == sections  # every section, in order, and nothing else
    assert set(targets) <= anchors(README)
    # the field workflow is on the first screen: in the contents, within the README's first 60 lines
    assert "in-the-field" in targets
    assert "](#in-the-field)" in "\n".join(text.splitlines()[:60])


def test_the_command_table_has_every_command_of_the_cli_once():
    table = section(README.read_text(encoding="utf-8"), "Commands")
    rows = re.findall(r"^\| `([a-z-]+)` \|", table, re.M)
    commands = cli_commands()
    assert len(commands) >= 15
    assert sorted(rows) == sorted(commands), "the README's command table and `sniffer --help` differ"
    for row in table.splitlines():
        if row.startswith("| `"):
            assert row.count("|") == 4 and "\n" not in row  # one line each: command, what, a page


def test_the_quick_start_is_what_ci_runs():
    """.ci/run runs the README's two quick-start commands as written (CI proves them on a clean checkout)."""
    text = README.read_text(encoding="utf-8")
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    quick = section(text, "Quick start")
    blocks = re.findall(r"^```sh\n(.*?)^```", quick, re.M | re.S)
    install, tests = blocks[0].strip(), blocks[1].strip()
    assert install.startswith("python3 -m venv .venv && ") and install.endswith("sniffer demo")
    assert "pytest" in tests and "install-system-deps.sh" in tests and "ruff check" in tests
    ci_lines = [line.strip() for line in ci.splitlines()]
    assert any(line.startswith(install) for line in ci_lines), install
    assert tests in ci_lines, tests


def test_the_readme_links_the_install_and_troubleshooting_pages_at_the_top():
    text = README.read_text(encoding="utf-8")
    head = text[:text.index("\n## Quick start\n")]
    assert "](docs/troubleshooting.md)" in head
    assert "](docs/install.md)" in section(text, "Quick start")


def test_every_page_in_docs_is_linked_from_the_readme():
    linked = {(README.parent / t.split("#")[0]).resolve() for t in LINK.findall(prose(README.read_text()))}
    orphans = [p.name for p in DOCS.glob("*.md") if p.resolve() not in linked]
    assert not orphans, f"pages the README does not link to: {orphans}"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_reaches_a_file_and_its_heading(page):
    bad = []
    for target in LINK.findall(prose(page.read_text(encoding="utf-8"))):
        if re.match(r"[a-z][a-z0-9+.-]*:", target):  # https:, mailto: ...
            continue
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            bad.append(f"{target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            bad.append(f"{target}: no heading #{anchor} in {dest.relative_to(ROOT)}")
    assert not bad, bad


def test_the_link_checker_catches_a_broken_link(tmp_path):
    """The checks above can fail: a missing file, a missing heading, a heading inside a code block."""
    (tmp_path / "a.md").write_text("# A page\n\n## Real heading: `--x`\n\n```toml\n# not a heading\n```\n")
    assert anchors(tmp_path / "a.md") == {"a-page", "real-heading---x"}
    text = "[ok](a.md#real-heading---x) [gone](b.md) [code](a.md#not-a-heading) `[in code](c.md)`"
    assert LINK.findall(prose(text)) == ["a.md#real-heading---x", "b.md", "a.md#not-a-heading"]


@pytest.mark.slow
def test_the_diagnosis_in_the_readme_is_the_tools_output(tmp_path):
    """The README's `sniffer diagnose` example, run as it says on the capture it says: every line it shows
    (a shortened excerpt) is a line of the real output, in the same order."""
    text = section(README.read_text(encoding="utf-8"), "Diagnose: what is wrong on the line")
    (sim,) = re.findall(r"`(sniffer simulate [^`]+)`", " ".join(text.split()))
    (block,) = re.findall(r"^```\n\$ (sniffer diagnose [^\n]+)\n(.*?)^```", text, re.M | re.S)
    cmd, shown = block
    sn = [sys.executable, "-m", "sniffer"]
    r = subprocess.run(sn + shlex.split(sim)[1:], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    r = subprocess.run(sn + shlex.split(cmd)[1:], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    real = r.stdout.splitlines()
    at = 0
    for line in (line for line in shown.splitlines() if line.strip()):
        assert line in real[at:], line
        at = real.index(line, at) + 1
