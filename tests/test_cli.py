"""The command line: --version, and mistakes reported in one line without a traceback."""
import subprocess
import sys

import pytest

import softflow as sf
from softflow.cli import main


def test_version(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"softflow {sf.__version__}"


def _one_line_error(capsys, argv):
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def test_output_in_a_missing_folder(tmp_path, capsys):
    target = tmp_path / "nowhere" / "demo.png"
    err = _one_line_error(capsys, ["demo", "--output", str(target)])
    assert err.startswith("softflow demo: error: --output")
    assert f"folder {str(target.parent)!r} does not exist" in err


def test_output_in_an_unknown_format(tmp_path, capsys):
    err = _one_line_error(capsys, ["demo", "--output", str(tmp_path / "demo.xyz")])
    assert "unknown image format .xyz" in err and ".png" in err and ".pdf" in err
    err = _one_line_error(capsys, ["demo", "--output", str(tmp_path / "demo")])
    assert "unknown image format (no suffix)" in err


def test_output_that_is_a_folder(tmp_path, capsys):
    err = _one_line_error(capsys, ["demo", "--output", str(tmp_path)])
    assert "is a directory" in err


def test_output_dir_that_is_a_file(tmp_path, capsys):
    f = tmp_path / "file.txt"
    f.write_text("")
    err = _one_line_error(capsys, ["figures", "--fig", "3", "--output-dir", str(f)])
    assert f"--output-dir {str(f)!r} is a file" in err


def test_other_failures_are_one_line_too_and_traceback_on_request(tmp_path, capsys,
                                                                   monkeypatch):
    import softflow.demo

    def broken():
        raise RuntimeError("the scene\nbroke")
    monkeypatch.setattr(softflow.demo, "paper_system", broken)
    err = _one_line_error(capsys, ["demo", "--no-plot"])
    assert "error: RuntimeError: the scene broke (softflow --traceback" in err
    with pytest.raises(RuntimeError, match="broke"):
        main(["--traceback", "demo", "--no-plot"])


def test_as_a_process_the_error_is_one_line(tmp_path):
    out = subprocess.run([sys.executable, "-m", "softflow.cli", "demo", "--output",
                          str(tmp_path / "missing" / "x.png")], capture_output=True, text=True)
    assert out.returncode == 1
    assert out.stderr.count("\n") == 1 and "does not exist" in out.stderr, out.stderr


@pytest.mark.parametrize("physics, warns", [(None, False), ("paper", True)])
def test_figures_run_the_examples_scenes_unless_asked_for_the_papers(tmp_path, physics, warns):
    """`softflow figures` draws the scenes of examples/paper_fig*.py (the
    tube's inertia modelled: no ModelWarning); --physics paper, the paper's
    own model, which softflow warns of (Fig. 4's tube: its water column's
    inertia)."""
    import warnings
    argv = ["figures", "--fig", "4", "--output-dir", str(tmp_path)]
    if physics:
        argv += ["--physics", physics]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(argv) == 0
    model = [w for w in caught if issubclass(w.category, sf.ModelWarning)]
    assert bool(model) == warns, [str(w.message)[:120] for w in model]
    assert (tmp_path / "fig4_C.png").is_file() and (tmp_path / "fig4_D.png").is_file()


def test_a_demo_run_that_compiled_first_reports_the_run_and_the_compile(monkeypatch, capsys):
    """A first run slower than settings.DEMO_COMPILED_RUN (it compiled the step loop)
    is run again: the steps' own time is reported, and the first's beside it."""
    from softflow.solve import settings
    monkeypatch.setattr(settings, "DEMO_COMPILED_RUN", -1.0)   # every run counts as a compile
    assert main(["demo", "--no-plot"]) == 0
    out = capsys.readouterr().out
    assert "solved " in out and "the first run took" in out
    assert "compiled softflow's step loop, once for this installation" in out
    monkeypatch.setattr(settings, "DEMO_COMPILED_RUN", 1e9)
    assert main(["demo", "--no-plot"]) == 0
    assert "the first run took" not in capsys.readouterr().out
