"""``continuum-mhe --help`` and ``--version`` answer without importing the estimators,
and both parsers are built from the one table of commands."""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from continuum_mhe.cli import entry

HEAVY = ("continuum_mhe.estimators", "continuum_mhe.cli.app", "numpy", "casadi", "numba", "scipy")


@pytest.mark.parametrize("argv", [["--help"], ["--version"], ["-h"]])
def test_help_and_version_import_nothing_heavy(argv):
    code = (
        "import sys\n"
        "from continuum_mhe.cli.entry import main\n"
        "try:\n"
        f"    main({argv!r})\n"
        "except SystemExit as e:\n"
        "    assert e.code == 0, e.code\n"
        f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    *shown, imported = r.stdout.strip().splitlines()
    assert imported == "[]"
    if argv == ["--version"]:
        assert shown == [f"continuum-mhe {entry.version()}"]
    else:
        assert any("estimate" in line for line in shown)


@pytest.mark.parametrize("preset", [None, "2"])
def test_the_executable_runs_numpys_blas_on_one_thread_unless_told(preset):
    """The executable sets ``OPENBLAS_NUM_THREADS`` to 1 where it is not set, before
    numpy loads its BLAS: the process then runs no BLAS thread besides its own (counted
    in ``/proc``); a value set outside is kept. The machine has at least two cores, or
    OpenBLAS would start no thread either way."""
    if not hasattr(os, "sched_getaffinity") or not Path("/proc/self/task").is_dir():
        pytest.skip("counts the process's threads in Linux's /proc")
    if len(os.sched_getaffinity(0)) < 2:
        pytest.skip("one core: OpenBLAS starts no thread either way")
    code = (
        "import os, sys\n"
        "sys.argv = ['continuum-mhe', 'check-robot', 'two-section']\n"
        "from continuum_mhe.cli.entry import main\n"
        "assert main() == 0\n"
        "import numpy\n"
        "print(os.environ['OPENBLAS_NUM_THREADS'], len(os.listdir('/proc/self/task')))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if preset is not None:
        env["OPENBLAS_NUM_THREADS"] = preset
    r = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600
    )
    assert r.returncode == 0, r.stderr
    value, threads = r.stdout.split()[-2:]
    assert value == (preset or "1")
    if preset is None:
        assert threads == "1"
    else:
        assert int(threads) >= 2


def test_the_installed_metadata_carries_the_package_s_version():
    """``--version`` and the estimate files' first line read ``__version__``; the
    package's metadata takes it when the package is built (pyproject.toml)."""
    from importlib import metadata

    import continuum_mhe

    assert entry.version() == continuum_mhe.__version__
    assert metadata.version("continuum-mhe") == continuum_mhe.__version__


def _commands(parser: argparse.ArgumentParser) -> list[tuple[str, str]]:
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return [(a.dest, str(a.help)) for a in sub._choices_actions]


def test_both_parsers_list_the_table_s_commands():
    from continuum_mhe.cli.app import build_parser
    from continuum_mhe.cli.program import COMMANDS

    table = [(c.name, c.help) for c in COMMANDS]
    full = build_parser()
    assert _commands(entry.overview_parser()) == table
    assert _commands(full) == table
    assert full.description == entry.DESCRIPTION


def test_each_command_module_defines_its_arguments_and_run():
    import importlib

    from continuum_mhe.cli.program import COMMANDS

    assert len({c.name for c in COMMANDS}) == len({c.module for c in COMMANDS}) == len(COMMANDS)
    for command in COMMANDS:
        module = importlib.import_module(f"continuum_mhe.cli.{command.module}")
        assert callable(module.add_arguments) and callable(module.run), command.name


def test_every_command_has_a_row_in_the_guide_s_table_of_commands():
    """The guide's table of commands (docs/guide/commands.md) names every command of
    the table (a new command without a row fails here)."""
    from pathlib import Path

    from continuum_mhe.cli.program import COMMANDS

    guide = Path(__file__).resolve().parents[1] / "docs" / "guide" / "commands.md"
    rows = [ln for ln in guide.read_text().splitlines() if ln.startswith("| `")]
    listed = {ln[3:].split("`")[0].split()[0] for ln in rows}
    assert {c.name for c in COMMANDS} <= listed, {c.name for c in COMMANDS} - listed


def test_a_command_goes_to_the_full_command_line(capsys):
    with pytest.raises(SystemExit) as exc:
        entry.main(["estimate", "--help"])
    assert exc.value.code == 0
    assert "--method" in capsys.readouterr().out


def test_public_names_resolve():
    import continuum_mhe
    import continuum_mhe.io

    for mod in (continuum_mhe, continuum_mhe.io):
        for name in mod.__all__:
            assert getattr(mod, name) is not None, name
    with pytest.raises(AttributeError):
        continuum_mhe.no_such_name  # noqa: B018


def test_step_after_run_suggests_reset():
    import numpy as np

    from continuum_mhe import Measurement, make_estimator, make_formulation

    est = make_estimator("ukf", make_formulation("bend"))
    est.run(np.array([0.0, 0.05]), np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"run\(\) left the estimator .* call reset\(\)"):
        est.step(Measurement(0.0, np.zeros(2)))
    est.reset()
    assert est.step(Measurement(0.0, np.zeros(2))).status == "uncertain"  # a new start


@pytest.mark.parametrize(
    ("module", "sig", "said", "code"),
    [
        # Ctrl-C while the entry point imports the full command line
        ("continuum_mhe.settings", "SIGINT", "continuum-mhe: interrupted\n", 130),
        # SIGTERM before the command line sets its handlers: killed, quietly
        ("continuum_mhe.settings", "SIGTERM", "", -signal.SIGTERM),
        # SIGTERM while the parser imports the command's module, the handlers set
        ("continuum_mhe.cli.estimate", "SIGTERM", "continuum-mhe: terminated\n", 143),
        ("continuum_mhe.cli.estimate", "SIGINT", "continuum-mhe: interrupted\n", 130),
    ],
    ids=["import-sigint", "import-sigterm", "parser-sigterm", "parser-sigint"],
)
def test_a_signal_during_start_up_says_one_line(tmp_path, module, sig, said, code):
    """Ctrl-C while the modules are still importing, or a signal while the parser
    imports the commands, is one line and 130 (SIGTERM: 143), never a 30-line
    KeyboardInterrupt traceback (entry.py, cli.py, settings.py ...); a SIGTERM before the
    command line sets its handlers kills it quietly. The signal is sent by an import hook
    when ``module`` is first looked for."""
    code_text = (
        "import os, signal, sys\n"
        # a child of a background job inherits SIGINT ignored, and Python then installs
        # no handler of its own: here the handler it installs when started from a
        # terminal (in the child itself: a hook run between fork and exec may block on
        # a lock another thread of the test's process held)
        "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
        "class Hook:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        f"        if name == {module!r}:\n"
        f"            os.kill(os.getpid(), signal.{sig})\n"
        "        return None\n"
        "sys.meta_path.insert(0, Hook())\n"
        "from continuum_mhe.cli.entry import main\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    out = tmp_path / "e.csv"
    argv = ["estimate", str(tmp_path / "m.csv"), "-o", str(out)]
    r = subprocess.run(
        [sys.executable, "-c", code_text, *argv], capture_output=True, text=True, timeout=300
    )
    assert (r.returncode, r.stderr) == (code, said)
    assert not out.exists()


def test_a_reader_that_leaves_stops_the_command_quietly_with_status_1():
    """``continuum-mhe ... | head`` where the reader has left before the command writes:
    no traceback and no bug report, exit status 1 (formats.md lists it)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "continuum_mhe", "check-robot", "two-section", "--samples", "50"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # the reader leaves before the command writes a line
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == 1
    assert "Traceback" not in err and "bug" not in err.lower()


def test_the_formulation_registry_and_its_names_agree():
    """A formulation is looked up by name in REGISTRY and typed by the FormulationName
    literal: the two name the same formulations; --formulation chooses among them."""
    from typing import get_args

    from continuum_mhe.model.registry import REGISTRY
    from continuum_mhe.model.settings import FORMULATIONS, FormulationName

    assert set(REGISTRY) == set(get_args(FormulationName))
    assert set(FORMULATIONS) <= set(REGISTRY)


def test_the_errors_and_warnings_the_library_raises_are_public_names():
    """Each error and warning the library raises, importable from ``continuum_mhe`` as
    the library's guide lists them (not only from the modules that raise them), and
    each of the kind it is documented as."""
    import continuum_mhe
    from continuum_mhe.estimators.reading_units import ReadingUnitsError
    from continuum_mhe.io.input_options import MountingError

    errors = ("UserError", "InputError", "SampleTimeError", "ReadingUnitsError", "MountingError",
              "FieldError", "MissingExtraError", "TimesWrittenAsOneError")  # fmt: skip
    for name in errors:
        assert issubclass(getattr(continuum_mhe, name), continuum_mhe.UserError), name
        assert name in continuum_mhe.__all__
    warned = ("RobotWarning", "RobotFileWarning", "MountingWarning", "UnitWarning",
              "DropoutWarning", "OptionWarning", "CutLineWarning",
              "UnobservableShapeWarning", "TensionsWarning", "TruthCoverageWarning",
              "BackendFallbackWarning", "FrameWarning", "TopicClockWarning",
              "TopicOrderWarning", "FigureWarning")  # fmt: skip
    for name in warned:
        assert issubclass(getattr(continuum_mhe, name), UserWarning), name
        assert name in continuum_mhe.__all__
    guide = (Path(__file__).parents[1] / "docs" / "guide" / "library.md").read_text()
    for name in (*errors, *warned):
        assert f"`{name}`" in guide, name  # the guide's list names each
    assert continuum_mhe.MountingError is MountingError
    assert continuum_mhe.ReadingUnitsError is ReadingUnitsError


def test_every_warning_class_of_the_library_is_a_public_name():
    """Each warning class the package defines is importable from ``continuum_mhe``, so
    that ``warnings.filterwarnings("error", category=...)`` can name it."""
    import ast

    import continuum_mhe

    src = Path(continuum_mhe.__file__).parent
    defined = {
        node.name
        for path in src.rglob("*.py")
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.ClassDef)
        and any(getattr(b, "id", "").endswith("Warning") for b in node.bases)
    }
    assert "TensionsWarning" in defined
    assert defined - set(continuum_mhe.__all__) == set()
