"""The README is a front page that tells the truth: its Python examples run as
written (each block after the first may use the names the earlier blocks define, as
a reader would), its set-up commands are the two that CI runs, in that order, its
pictures and links exist, and its measurement history lives elsewhere. The docs'
pages are their own (no README includes) and install from the repository."""
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
TEXT = README.read_text()
BLOCKS = re.findall(r"```python\n(.*?)```", TEXT, re.S)

#: README's set-up commands for a fresh machine: the runtime install and the demo,
#: then what the tests need and the tests
SETUP = ['pip install -e . && softflow demo', 'pip install -e ".[dev]" && pytest']


def _section(text, title):
    """The text of the ``## title`` section (up to the next ``## ``)."""
    start = text.index(f"\n## {title}")
    end = text.find("\n## ", start + 1)
    return text[start:end if end >= 0 else None]


def test_readme_python_examples_run(tmp_path, monkeypatch):
    assert len(BLOCKS) >= 3
    monkeypatch.chdir(tmp_path)          # result.to_csv("run.csv") writes here
    namespace = {}
    for i, block in enumerate(BLOCKS):
        exec(compile(block, f"README.md python block {i}", "exec"), namespace)
    assert (tmp_path / "run.csv").exists()


def test_the_first_network_needs_no_optional_extra():
    """A reader who ran only the first set-up command can run the first block."""
    first = BLOCKS[0]
    assert "to_csv" in first
    for optional in ("to_dataframe", "to_xarray", "import pandas", "import xarray"):
        assert optional not in first, optional


def test_the_set_up_is_two_commands_and_ci_runs_them_in_order():
    setup = _section(TEXT, "Set-up")
    commands = [b.strip() for b in re.findall(r"```(?:bash|sh|console)?\n(.*?)```", setup, re.S)]
    assert commands == SETUP
    ci = [line.split("#")[0].strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    positions = [ci.index(command) for command in SETUP]
    assert positions == sorted(positions), ".ci/run must run README's commands in order"


def test_readme_is_a_front_page():
    lines = TEXT.splitlines()
    assert len(lines) <= 300, len(lines)
    for title in ("Set-up", "A first network", "Limitations", "Documentation", "How to cite"):
        assert f"\n## {title}" in TEXT, title
    dated = re.findall(r"\b20\d\d-\d\d-\d\d\b", TEXT)
    assert not dated, f"dated measurements belong in benchmarks/README.md or CHANGELOG.md: {dated}"
    assert "pip install softflow" not in TEXT          # no index serves it
    assert "FONS: a Python framework" in TEXT             # the paper, cited


def test_readme_pictures_and_links_exist():
    targets = re.findall(r"!?\[[^\]]*\]\(([^)#\s]+)\)", TEXT)
    local = [t for t in targets if "://" not in t]
    assert any(t.endswith(".png") for t in local), "the README shows a figure"
    for target in local:
        assert (ROOT / target).exists(), target
    assert (ROOT / "CITATION.cff").is_file()


def test_docs_pages_are_their_own_and_install_from_the_repository():
    docs = ROOT / "docs"
    pages = [docs / "index.md", docs / "getting-started.md", *sorted((docs / "guide").glob("*.md"))]
    for page in pages:
        text = page.read_text()
        assert "README.md" not in text or "{include}" not in text, f"{page.name} includes the README"
        assert not re.search(r"\b20\d\d-\d\d-\d\d\b", text), f"{page.name} carries a date stamp"
        assert not re.search(r"pip install ['\"]?softflow\b", text), \
            f"{page.name}: no index serves softflow; install from the repository"
    for page in (docs / "index.md", docs / "getting-started.md"):
        assert 'pip install -e .' in page.read_text(), page.name
