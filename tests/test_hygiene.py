"""Lint, types and the README's documented commands, run as part of the suite."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(*cmd: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=False)


def test_ruff_clean():
    ruff = shutil.which("ruff") or str(Path(sys.executable).with_name("ruff"))
    r = _run(ruff, "check", "src", "tests")
    assert r.returncode == 0, r.stdout + r.stderr


def test_mypy_clean():
    r = _run(sys.executable, "-m", "mypy")
    assert r.returncode == 0, r.stdout + r.stderr


def test_ci_runs_exactly_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    test_cmd = re.search(r"# test command\n(.+)\n", readme)
    assert test_cmd, "README must mark its test command with '# test command'"
    assert test_cmd.group(1).strip() in ci.splitlines()


def test_readme_demo_command_runs(tmp_path):
    readme = (ROOT / "README.md").read_text()
    demo = re.search(r"# main job\n(.+)\n", readme)
    assert demo and demo.group(1).strip().endswith("continuum-mhe demo")
    exe = Path(sys.executable).with_name("continuum-mhe")
    r = _run(str(exe), "demo", "--out", str(tmp_path / "demo"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    for name in ("demo_trajectory_3d.png", "demo_states.png", "estimates_mhe.csv"):
        assert (tmp_path / "demo" / name).stat().st_size > 0
    assert "MHE" in r.stdout and "EKF" in r.stdout and "UKF" in r.stdout


def _readme_examples() -> list[str]:
    """README lines that are plain CLI examples on files they create themselves."""
    skip = ("--port", "reproduce", "benchmark", " demo", "--topic", "live ", " plot ")
    return [
        ln.strip()
        for ln in (ROOT / "README.md").read_text().splitlines()
        if ln.startswith("continuum-mhe ") and not any(k in ln for k in skip)
    ]


def test_readme_cli_examples_run(tmp_path):
    """Every plain CLI example line of the README runs, in order, in one folder."""
    lines = _readme_examples()
    assert len(lines) >= 4
    exe = str(Path(sys.executable).with_name("continuum-mhe"))
    for line in lines:
        r = _run(exe, *line.split()[1:], cwd=tmp_path)
        assert r.returncode == 0, f"{line}: {r.stderr}"


def test_readme_python_examples_run(tmp_path, monkeypatch):
    """Every ```python block of the README runs as written (in a scratch folder)."""
    import re

    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
    assert len(blocks) >= 2
    monkeypatch.chdir(tmp_path)
    for code in blocks:
        namespace: dict[str, object] = {}
        exec(compile(code, "README.md", "exec"), namespace)
    assert (tmp_path / "two_section_estimates.csv").read_text().startswith("t,x,y,z,theta_1,")
