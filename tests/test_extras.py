"""Optional parts: a feature whose extra is missing says which ``pip install`` to run,
in one line, exits 2 and writes nothing. The missing package is simulated by blocking
its import (``sys.modules[name] = None`` makes ``import name`` raise ImportError)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from continuum_mhe.cli import main
from continuum_mhe.extras import EXTRAS, MissingExtraError, require

ROOT = Path(__file__).resolve().parents[1]


def _block(monkeypatch: pytest.MonkeyPatch, *modules: str) -> None:
    for name in modules:
        for loaded in [m for m in sys.modules if m == name or m.startswith(name + ".")]:
            monkeypatch.delitem(sys.modules, loaded)
        monkeypatch.setitem(sys.modules, name, None)


def _one_error_line(err: str, extra: str, prog: str = "continuum-mhe") -> None:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"{prog}: error:"), lines[0]
    assert f"pip install 'continuum-mhe[{extra}]'" in lines[0]


def test_require_names_the_extra(monkeypatch):
    _block(monkeypatch, "do_mpc")
    with pytest.raises(MissingExtraError, match=r"pip install 'continuum-mhe\[peers\]'"):
        require("do_mpc", "peers", "benchmark", package="do-mpc")
    assert require("json", "peers", "x").dumps([1]) == "[1]"


def test_an_installed_package_that_does_not_import_is_not_called_missing(monkeypatch, tmp_path):
    """A package that is installed but whose import fails (a version older than the
    extra asks for: do-mpc 4.6 under CasADi 3.8) is said to be installed and not to
    import, with the error and the ``pip install ... --upgrade``; one that is not
    installed is said to be missing."""
    package = tmp_path / "stale_peer"
    package.mkdir()
    (package / "__init__.py").write_text(
        "raise ImportError(\"cannot import name 'Inf' from 'numpy'\")\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(MissingExtraError) as info:
        require("stale_peer", "peers", "benchmark", package="stale-peer")
    assert str(info.value) == (
        "benchmark needs stale-peer, which is installed but does not import here "
        "(ImportError: cannot import name 'Inf' from 'numpy'): a version too old?: "
        "pip install 'continuum-mhe[peers]' --upgrade"
    )
    with pytest.raises(MissingExtraError, match="which is not installed: pip install"):
        require("no_such_peer_here", "peers", "benchmark")


def test_benchmark_without_do_mpc_times_the_rest(monkeypatch, tmp_path, capsys):
    """A peer that is not installed is not timed, and the report says what to install,
    as for acados: the other contenders are timed."""
    import json

    _block(monkeypatch, "do_mpc")
    out = tmp_path / "bench.json"
    argv = ["benchmark", "--horizons", "5", "--duration", "0.5", "--json", str(out),
            "--skip", "fatrop", "--skip", "sqp-hpipm", "--skip", "acados",
            "--loss-horizons", "none", "--repeats", "1", "--memory-samples", "0",
            "--interpreted-peers"]  # fmt: skip
    assert main(argv) == 0
    hint = "needs do-mpc, which is not installed: pip install 'continuum-mhe[peers]'"
    assert f"do-mpc: not timed: {hint}" in " ".join(capsys.readouterr().out.split())
    report = json.loads(out.read_text())
    assert report["skipped"]["do-mpc"] == hint
    assert main(argv) == 2  # the report exists: kept without --overwrite
    assert "exists; give --overwrite" in capsys.readouterr().err
    assert {r["method"] for r in report["results"]} >= {"fast", "ipopt"}
    assert "do-mpc" not in {r["method"] for r in report["results"]}


def test_reproduce_scheduler_without_dask_writes_no_folder(monkeypatch, tmp_path, capsys):
    _block(monkeypatch, "dask")
    out = tmp_path / "results"
    code = main(["reproduce", "--quick", "--out", str(out), "--scheduler", "tcp://127.0.0.1:1"])
    assert code == 2
    _one_error_line(capsys.readouterr().err, "dask")
    assert not out.exists()


@pytest.mark.parametrize("command", ["single", "sections"])
def test_rod_generators_without_pyelastica(monkeypatch, tmp_path, capsys, command):
    _block(monkeypatch, "elastica")
    target = tmp_path / "rod.csv" if command == "single" else tmp_path / "out"
    assert main(["rod", command, "-o", str(target)]) == 2
    _one_error_line(capsys.readouterr().err, "rod")
    assert list(tmp_path.iterdir()) == []


def test_live_without_pyserial(monkeypatch):
    from continuum_mhe.stream.reader import open_port

    _block(monkeypatch, "serial")
    with pytest.raises(MissingExtraError, match=r"pyserial.*continuum-mhe\[robot\]"):
        open_port("/dev/ttyACM0", 115200)


def test_calibrate_without_pyserial(monkeypatch, capsys):
    """The missing package, not the board: one line naming ``calibrate`` and the pip
    install, exit 2."""
    _block(monkeypatch, "serial")
    assert main(["calibrate", "--port", "/dev/ttyACM0"]) == 2
    err = capsys.readouterr().err
    _one_error_line(err, "robot")
    assert "calibrate needs pyserial" in err
    assert "live" not in err and "board" not in err and "serial ports" not in err


def test_bag_without_rosbags(monkeypatch, tmp_path, capsys):
    bag = tmp_path / "run.bag"
    bag.write_bytes(b"#ROSBAG V2.0\n")
    _block(monkeypatch, "rosbags")
    code = main(["estimate", str(bag), "-o", str(tmp_path / "e.csv")])
    assert code == 2
    err = capsys.readouterr().err
    _one_error_line(err, "robot")
    assert "cannot read robot log" not in err  # the missing package, not a corrupt file
    assert not (tmp_path / "e.csv").exists()
    from continuum_mhe.extras import MissingExtraError
    from continuum_mhe.io.robot_logs import read_imu_log

    with pytest.raises(MissingExtraError):  # the type a caller catches
        read_imu_log(bag)


def test_pyproject_extras_match_the_documented_ones():
    """The extras in pyproject.toml are the ones the messages name, and ``test`` pulls
    in all of them; the core needs none of the optional packages."""
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = meta["optional-dependencies"]
    assert set(EXTRAS) <= set(extras)
    test_self = [d for d in extras["test"] if d.startswith("continuum-mhe[")]
    assert test_self and set(EXTRAS) <= set(test_self[0][len("continuum-mhe[") : -1].split(","))
    core = " ".join(meta["dependencies"]).lower()
    for optional in ("pyserial", "rosbags", "mcap", "do-mpc", "filterpy", "dask", "pyelastica"):
        assert optional not in core
    assert isinstance(meta["license"], str) and meta["license-files"] == ["LICENSE"]
    assert not any(c.startswith("License ::") for c in meta["classifiers"])
