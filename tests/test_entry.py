"""``continuum-mhe --help`` and ``--version`` answer without importing the estimators,
and their table of commands is the full command line's."""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from continuum_mhe import entry

HEAVY = ("continuum_mhe.estimators", "continuum_mhe.cli", "numpy", "casadi", "numba", "scipy")


@pytest.mark.parametrize("argv", [["--help"], ["--version"], ["-h"]])
def test_help_and_version_import_nothing_heavy(argv):
    code = (
        "import sys\n"
        "from continuum_mhe.entry import main\n"
        "try:\n"
        f"    main({argv!r})\n"
        "except SystemExit as e:\n"
        "    assert e.code == 0, e.code\n"
        f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    *shown, imported = r.stdout.strip().splitlines()
    assert imported == "[]"
    if argv == ["--version"]:
        assert shown == [f"continuum-mhe {entry.version()}"]
    else:
        assert any("estimate" in line for line in shown)


def _commands(parser: argparse.ArgumentParser) -> list[tuple[str, str]]:
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return [(a.dest, str(a.help)) for a in sub._choices_actions]


def test_the_table_is_the_full_command_line():
    from continuum_mhe.cli import build_parser

    full = build_parser()
    assert _commands(entry.overview_parser()) == _commands(full)
    assert full.description == entry.DESCRIPTION


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
    assert est.step(Measurement(0.0, np.zeros(2))).status == "ok"
