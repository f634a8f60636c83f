"""The README's Python examples run as written (each block after the first
may use the names the earlier blocks define, as a reader would)."""
import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)


def test_readme_python_examples_run(tmp_path, monkeypatch):
    assert len(BLOCKS) >= 3
    monkeypatch.chdir(tmp_path)          # result.to_csv("run.csv") writes here
    namespace = {}
    for i, block in enumerate(BLOCKS):
        exec(compile(block, f"README.md python block {i}", "exec"), namespace)
    assert (tmp_path / "run.csv").exists()
