"""Lint, types and the README's documented commands, run as part of the suite."""

from __future__ import annotations

import ast
import io
import os
import re
import shutil
import subprocess
import sys
import tokenize
from pathlib import Path
from typing import Any

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(*cmd: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=False, timeout=600)


def test_ruff_clean():
    """ruff's lint and its format (as ``ruff format`` would leave the files)."""
    ruff = shutil.which("ruff") or str(Path(sys.executable).with_name("ruff"))
    r = _run(ruff, "check", "src", "tests", "tools")
    assert r.returncode == 0, r.stdout + r.stderr
    r = _run(ruff, "format", "--check", "src", "tests", "tools")
    assert r.returncode == 0, r.stdout + r.stderr


def test_every_tool_answers_help():
    """Each script of tools/ prints its usage for --help (standard output starting
    ``usage: NAME.py``) and exits 0, without reading --help as an argument or running
    its study, in one process: each run as a script with --help as its argument."""
    code = (
        "import contextlib, io, runpy, sys\n"
        "from pathlib import Path\n"
        "failed = []\n"
        "sys.path.insert(0, 'tools')\n"
        "for path in sorted(Path('tools').glob('*.py')):\n"
        "    sys.argv = [str(path), '--help']\n"
        "    out = io.StringIO()\n"
        "    try:\n"
        "        with contextlib.redirect_stdout(out):\n"
        "            runpy.run_path(str(path), run_name='__main__')\n"
        "        failed.append(f'{path}: no SystemExit')\n"
        "    except SystemExit as exc:\n"
        "        if exc.code not in (0, None):\n"
        "            failed.append(f'{path}: exit {exc.code}')\n"
        "        elif not out.getvalue().startswith(f'usage: {path.name}'):\n"
        "            failed.append(f'{path}: no usage: {out.getvalue()[:80]!r}')\n"
        "    except BaseException as exc:\n"
        "        failed.append(f'{path}: {type(exc).__name__}: {exc}')\n"
        "print('\\n'.join(failed))\n"
        "sys.exit(1 if failed else 0)\n"
    )
    r = _run(sys.executable, "-c", code)
    assert r.returncode == 0, r.stdout + r.stderr


def test_mypy_clean():
    r = _run(sys.executable, "-m", "mypy")
    assert r.returncode == 0, r.stdout + r.stderr


def test_import_layers_kept():
    """The contracts of pyproject.toml's ``[tool.importlinter]`` (import-linter)."""
    r = _run(sys.executable, "-c", "import sys; from importlinter.cli import lint_imports; "
             "sys.exit(lint_imports(config_filename='pyproject.toml'))")  # fmt: skip
    assert r.returncode == 0, r.stdout + r.stderr


def test_no_import_cycles():
    """No module imports itself through others, at import time or inside a function
    (grimp's import graph, ordered by graphlib)."""
    import graphlib

    import grimp

    graph = grimp.build_graph("continuum_mhe")
    order = graphlib.TopologicalSorter(
        {m: graph.find_modules_directly_imported_by(m) for m in graph.modules}
    )
    try:
        order.prepare()
    except graphlib.CycleError as exc:
        raise AssertionError(f"import cycle: {' -> '.join(exc.args[1])}") from None


def test_every_error_and_warning_of_the_library_is_exported():
    """Each class of the library (the command line's package aside) that derives from
    ``UserError`` or ``UserWarning``, directly or through another, is importable from
    ``continuum_mhe``, as the library guide says (found in the source's syntax trees)."""
    import ast

    import continuum_mhe

    root = Path(continuum_mhe.__file__).parent
    bases: dict[str, set[str]] = {}
    for path in root.rglob("*.py"):
        if "cli" in path.relative_to(root).parts:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef):
                names = {
                    b.id if isinstance(b, ast.Name) else getattr(b, "attr", "") for b in node.bases
                }
                bases[node.name] = names
    public = {"UserError", "UserWarning"}
    while True:
        more = {name for name, of in bases.items() if of & public} - public
        if not more:
            break
        public |= more
    public -= {"UserWarning"}
    missing = sorted(n for n in public if n not in continuum_mhe._EXPORTS)
    assert not missing, f"not importable from continuum_mhe: {missing}"


def test_ci_runs_exactly_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    test_cmd = re.search(r"# test command\n(.+)\n", readme)
    assert test_cmd, "README must mark its test command with '# test command'"
    assert test_cmd.group(1).strip() in ci.splitlines()


def _table_rows(text: str, sep: str) -> dict[str, list[str]]:
    """Rows of a printed table whose first cell is MHE, EKF or UKF: name -> other cells."""
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip(sep).split(sep)]
        if cells and cells[0] in ("MHE", "EKF", "UKF"):
            rows[cells[0]] = cells[1:]
    return rows


#: The README's length, words (split on white space): the documentation site holds the rest.
README_WORDS = 1500


def test_the_readme_is_short():
    """The README stays a short guide of at most :data:`README_WORDS` words."""
    words = len((ROOT / "README.md").read_text(encoding="utf-8").split())
    assert words <= README_WORDS, f"README.md has {words} words, at most {README_WORDS}"


def test_readme_demo_command_runs_and_prints_the_readme_numbers(tmp_path):
    """``continuum-mhe demo`` runs as the README says, and its errors are the README's
    table (tip mean mm and %, tip max mm, theta RMSE deg, to the printed precision)
    and its phi RMSE the README's 'about N degrees'. Times depend on the machine."""
    readme = (ROOT / "README.md").read_text()
    demo = re.search(r"# main job\n(.+)\n", readme)
    assert demo and demo.group(1).strip().endswith("continuum-mhe demo")
    exe = Path(sys.executable).with_name("continuum-mhe")
    r = _run(str(exe), "demo", "--out", str(tmp_path / "demo"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    for name in ("demo_trajectory_3d.png", "demo_states.png", "estimates_mhe.csv"):
        assert (tmp_path / "demo" / name).stat().st_size > 0
    section = readme.split("## What the demo prints", 1)[1].split("\n## ", 1)[0]
    documented = _table_rows(section, "|")
    printed = _table_rows(r.stdout, "\u2502")  # rich's box-drawing column separator
    assert set(documented) == set(printed) == {"MHE", "EKF", "UKF"}, r.stdout
    for method, cells in documented.items():
        for doc, got in zip(cells[:4], printed[method][:4]):
            step = 10.0 ** -len(doc.split(".")[1])  # one unit of the README's last digit
            assert abs(float(got) - float(doc)) <= step * (1 + 1e-9), (method, doc, got)
    phi = re.search(r"phi RMSE \(about (\d+)\N{DEGREE SIGN}\)", section)
    assert phi, "the README states the phi RMSE"
    for cells in printed.values():
        assert abs(float(cells[4]) - float(phi.group(1))) <= 1.0


def _readme_examples() -> list[str]:
    """README lines that are plain CLI examples (a serial port, the long ``reproduce``
    and ``benchmark`` runs and the demo, run by its own test, aside)."""
    skip = ("--port", "reproduce", "benchmark", " demo", "--topic", "live ")
    return [
        ln.strip()
        for ln in (ROOT / "README.md").read_text().splitlines()
        if ln.startswith("continuum-mhe ") and not any(k in ln for k in skip)
    ]


def _readme_inputs(folder: Path, page: Path = ROOT / "README.md") -> None:
    """The files the "five steps" of ``page`` (the README's, or the guide's) start from,
    as a user would have them: the page's robot file as ``my_robot.toml``, and the
    shipped two-section rod recording copied to the names the page gives (``rest.csv``,
    ``run.csv``, ``run_truth.csv``)."""
    readme = page.read_text()
    (robot,) = re.findall(r"```toml\n(.*?)```", readme, re.S)
    (folder / "my_robot.toml").write_text(robot)
    rod = ROOT / "src/continuum_mhe/data/rod2"
    copies = re.search(r"copy\s+`src/continuum_mhe/data/rod2/(.*?) to (.*?)[.;]\s", readme, re.S)
    assert copies, f"{page.name} says which shipped recordings the five steps copy"
    sources = re.findall(r"(spatial-tendon_\w+\.csv)", copies.group(1))
    targets = re.findall(r"`(\w+\.csv)`", copies.group(2))
    assert len(sources) == len(targets) == 3, (sources, targets)
    for source, target in zip(sources, targets):
        shutil.copyfile(rod / source, folder / target)


def test_readme_cli_examples_run(tmp_path, monkeypatch, capsys):
    """Every plain CLI example line of the README runs, in order, in one folder, and the
    five steps' estimate is what the README and the guide's page of those steps say of it.

    They run in this process, through the executable's own entry point
    (``continuum_mhe.cli.entry.main``, what the ``continuum-mhe`` script calls): a fresh
    interpreter per line would spend over a second importing each time (20 s of the suite);
    the executable itself is run by the demo test above and ``test_signals``."""
    from continuum_mhe.cli.entry import main

    lines = _readme_examples()
    assert len(lines) >= 4
    _readme_inputs(tmp_path)
    monkeypatch.chdir(tmp_path)
    for line in lines:
        capsys.readouterr()  # a failure shows this line's output only
        try:
            code = main(line.split()[1:])
        except SystemExit as exc:  # argparse's own exits (an option the CLI lacks: 2)
            code = exc.code
        assert code == 0, f"{line}: {capsys.readouterr().err}"
    # the five steps' numbers, as the README and the guide's page of the same steps give
    # them: the mean tip error (to their last digit) and the statuses the estimate wrote
    import json

    from continuum_mhe.io.state_tables import read_state_table

    readme = (ROOT / "README.md").read_text()
    guide = (ROOT / "docs/guide/your-robot.md").read_text()
    said = re.search(
        r"mean tip error is ([\d.]+) mm \(([\d.]+) % of the 0.3 m robot\);\s+(\d+) of its"
        r"\s+(\d+) rows are\s+`inconsistent`",
        readme,
    )
    in_guide = re.search(r"mean tip error is ([\d.]+) mm \(([\d.]+) % of the 0.3 m robot\)", guide)
    counts = re.search(r"`estimate` says `((?:[a-z-]+: \d+(?:, )?)+)`", guide)
    assert said and in_guide and counts, "README.md and your-robot.md state the five steps' result"
    capsys.readouterr()
    assert main(["evaluate", "run_est.csv", "run_truth.csv", "--robot", "my_robot_cal.toml",
                 "--json"]) == 0  # fmt: skip
    report = json.loads(capsys.readouterr().out)
    for doc, key in [*zip(said.groups()[:2], ("tip_mean_mm", "tip_mean_pct")),
                     *zip(in_guide.groups(), ("tip_mean_mm", "tip_mean_pct"))]:  # fmt: skip
        step = 10.0 ** -len(doc.split(".")[1])  # one unit of the page's last digit
        assert abs(report[key] - float(doc)) <= step * (1 + 1e-9), (key, doc, report[key])
    status = [str(s) for s in read_state_table("run_est.csv").status]
    written = {name: status.count(name) for name in sorted(set(status))}
    guide_counts = {k: int(v) for k, v in re.findall(r"([a-z-]+): (\d+)", counts.group(1))}
    assert guide_counts == written
    assert (int(said.group(3)), int(said.group(4))) == (written["inconsistent"], len(status))


#: The pages a new user reads first, beside the README: their command lines run as
#: written, from the repository root (the ``src/continuum_mhe/data/...`` paths).
GUIDE_PAGES = (
    "docs/guide/quickstart.md",
    "docs/guide/your-robot.md",
    "docs/guide/commands.md",
    "docs/workflow.md",
    "docs/tendon.md",
)

#: A file named for the reader's own (``LOG.csv``), unless an example writes it (``-o``)
_PLACEHOLDER = re.compile(r"\b[A-Z][A-Z0-9_-]*\.(?:csv|toml|png|rrd|mcap|bag)\b")

#: ``T=$(python -c "...")``: a shell variable a page's later lines use as ``$T``
_SHELL_VARIABLE = re.compile(r'(\w+)=\$\(python -c "(.*)"\)')


def _page_commands(page: Path) -> list[str]:
    """The lines of ``page``'s shell blocks that are CLI examples or set a variable they
    use, their trailing comments cut: a serial port, a robot log the package does not
    ship (``--topic``), the Cosserat-rod generators (minutes), the long runs, optional
    parts (``[--truth TRUTH.csv]``) and the reader's own files (:data:`_PLACEHOLDER`)
    left out."""
    skip = ("--port", "--topic", "continuum-mhe rod ", "reproduce", "benchmark", " demo", "[")
    lines, fence = [], None  # the open block's language ("" for none), None outside one
    written: set[str] = set()  # the files the lines kept write with -o
    for line in page.read_text().splitlines():
        if line.startswith("```"):
            fence = line[3:].strip() if fence is None else None
            continue
        line = re.sub(r"\s+#.*$", "", line).strip()
        if fence not in ("", "bash"):
            continue
        if line.startswith("continuum-mhe ") and not any(k in line for k in skip):
            writes = set(re.findall(r"(?:-o|--output) (\S+)", line))
            if set(_PLACEHOLDER.findall(line)) <= written | writes:
                lines.append(line)
                written |= writes
        elif _SHELL_VARIABLE.fullmatch(line):
            lines.append(line)
    return lines


@pytest.mark.parametrize("page", GUIDE_PAGES)
def test_guide_pages_cli_examples_run(page, tmp_path, monkeypatch, capsys):
    """Every plain CLI example line of a guide page runs, in order, in one folder that
    holds the repository's ``src`` (a link) and, for a page of the five steps, the
    files it says to copy; in this process, as the README's run
    (:func:`test_readme_cli_examples_run`)."""
    import contextlib
    import shlex

    from continuum_mhe.cli.entry import main

    path = ROOT / page
    lines = _page_commands(path)
    assert any(ln.startswith("continuum-mhe ") for ln in lines), page
    (tmp_path / "src").symlink_to(ROOT / "src", target_is_directory=True)
    if re.search(r"copy\s+`src/continuum_mhe/data/rod2/", path.read_text()):
        _readme_inputs(tmp_path, path)
    monkeypatch.chdir(tmp_path)
    variables: dict[str, str] = {}
    for line in lines:
        if (assignment := _SHELL_VARIABLE.fullmatch(line)) is not None:
            printed = io.StringIO()
            with contextlib.redirect_stdout(printed):
                exec(assignment.group(2), {})
            variables[assignment.group(1)] = printed.getvalue().strip()
            continue
        for name, value in variables.items():
            line = line.replace(f"${name}", shlex.quote(value))
        capsys.readouterr()  # a failure shows this line's output only
        try:
            code = main(shlex.split(line)[1:])
        except SystemExit as exc:  # argparse's own exits (an option the CLI lacks: 2)
            code = exc.code
        assert code == 0, f"{page}: {line}: {capsys.readouterr().err}"


LIBRARY_GUIDE = ROOT / "docs" / "guide" / "library.md"


def test_library_guide_python_examples_run(tmp_path, monkeypatch):
    """Every ```python block of the library guide (docs/guide/library.md) runs as
    written (in a scratch folder)."""
    blocks = re.findall(r"```python\n(.*?)```", LIBRARY_GUIDE.read_text(), re.S)
    assert len(blocks) >= 2
    monkeypatch.chdir(tmp_path)
    spaces = []
    for code in blocks:
        namespace: dict[str, Any] = {}
        exec(compile(code, str(LIBRARY_GUIDE), "exec"), namespace)
        spaces.append(namespace)
    # the first example's batch run estimates its recording: finite, within 1 cm of the tip
    first = spaces[0]
    out, truth = first["series"].output, first["rec"].truth
    assert out.shape == truth.shape and np.all(np.isfinite(out))
    assert np.mean(np.linalg.norm(out[:, :3] - truth[:, :3], axis=1)) < 0.01
    assert first["est"].status == "uncertain"  # a start's first row, unconfirmed
    assert (tmp_path / "two_section_estimates.csv").read_text().startswith("t,x,y,z,theta_1,")
    # the policy's example: the counts its comments give
    (policy,) = [ns for ns in spaces if "health" in ns]
    health = policy["health"]
    assert (health.frozen_samples, health.first_freezes) == (
        25,
        {0: 2.0},
    )  # held longer than 0.2 s: from 2.25 s
    assert (health.restarts, health.gap_resets, health.bad_starts) == (0, 1, 0)
    # the scoring example: what the text after it says it prints, and with the noise the
    # simulated recording has
    (scored,) = [ns for ns in spaces if "calibration" in ns]
    calibration = scored["calibration"]
    assert (round(scored["metrics"].tip_mean_mm, 2), round(calibration.coverage["x"], 2)) == (
        2.43,
        1.0,
    )
    assert round(calibration.tip_nees, 2) == 0.66
    from continuum_mhe import NoiseSettings, make_estimator, make_formulation
    from continuum_mhe.evaluation.metrics import compute_calibration

    exact = NoiseSettings(reading_bias_std=0.0, model_error_std=0.0)
    rec = scored["rec"]
    series = make_estimator("ekf", make_formulation("bend", noise=exact)).run(rec.t, rec.z)
    kept = series.rows(series.t >= 1.0)
    rows, at = scored["rows"], scored["at"]
    ours = compute_calibration(
        kept.output[rows], kept.std[rows], at, kept.names, scored["truth"].names
    )
    assert (round(ours.coverage["x"], 2), round(ours.tip_nees, 2)) == (0.96, 2.19)
    # the CSV example: read back, estimated within 1 cm, x, y, z written with its header
    (csv_example,) = [ns for ns in spaces if "table" in ns]
    tip = np.loadtxt(tmp_path / "tip.csv", delimiter=",", skiprows=1)
    truth = csv_example["rec"].truth
    assert tip.shape == (len(truth), 4)
    np.testing.assert_array_equal(tip[:, 0], csv_example["table"].t)
    assert np.mean(np.linalg.norm(tip[:, 1:] - truth[:, :3], axis=1)) < 0.01
    # the twisting rod: the twist states, the calibrated gyro biases held
    (twist,) = [ns for ns in spaces if "twisting" in ns]
    assert twist["twisting"].formulation.imu_twist
    assert not twist["twisting"].formulation.estimate_gyro_bias
    truth = np.genfromtxt(ROOT / "src/continuum_mhe/data/rod2/spatial_truth.csv",
                          delimiter=",", names=True)  # fmt: skip
    tip = np.column_stack([truth["x"], truth["y"], truth["z"]])
    assert np.mean(np.linalg.norm(twist["series"].output[:, :3] - tip, axis=1)) < 0.01
    # the raw recording's model: the direct one with the gyro biases, as make_formulation
    (raw,) = [ns for ns in spaces if "data" in ns and "fx" not in ns]
    from continuum_mhe import make_formulation

    assert raw["data"].formulation == make_formulation("direct", raw["robot"])
    assert raw["data"].formulation.estimate_gyro_bias and len(raw["series"].t) == 601
    # the same recording as arrays through raw_measurements: the same estimates
    untensioned = [ns for ns in spaces if "read_raw_imus" in ns and "Tensions" not in ns]
    (arrays,) = [ns for ns in untensioned if "series" in ns]
    np.testing.assert_allclose(arrays["series"].output, raw["series"].output, atol=1e-12)
    # the control loop's conversion and steps, sample by sample: the batch run's estimate
    (loop,) = [ns for ns in untensioned if "TensionStream" not in ns and "series" not in ns]
    batch_ekf = make_estimator("ekf", make_formulation("direct", raw["robot"]))
    ekf_series = batch_ekf.run(arrays["raw"].t[:50], arrays["z"][:50])
    np.testing.assert_allclose(loop["estimate"].output, ekf_series.output[-1], rtol=0, atol=1e-12)
    assert loop["estimate"].status == ekf_series.status[-1] == "ok"
    # raw readings simulated and estimated with the model that describes them: the tip
    # within 1 mm, each axis's 95 % intervals holding the truth 85 to 99.9 % of the time
    (simulated,) = [ns for ns in spaces if "raw_readings" in ns]
    tip = simulated["series"].output[:, :3]
    assert np.mean(np.linalg.norm(tip - simulated["rec"].truth[:, :3], axis=1)) < 1e-3
    assert np.all(
        (simulated["inside"].mean(axis=0) > 0.85) & (simulated["inside"].mean(axis=0) < 0.999)
    )
    # the tendon robot: the batch run within 5 mm of the truth at the tip, with its tip
    # force's standard deviation; the online steps give the batch run's estimates
    (batch,) = [ns for ns in spaces if "fx" in ns]
    (online,) = [ns for ns in spaces if "estimates" in ns]
    truth = np.loadtxt(str(batch["folder"] / "force-29_truth.csv"), delimiter=",", skiprows=1)
    tip = batch["series"].output[:, :3]
    assert np.mean(np.linalg.norm(tip - truth[:, 1:4], axis=1)) < 0.005
    assert np.all(batch["std_fx"] > 0)
    stepped = np.array([e.output for e in online["estimates"]])
    np.testing.assert_array_equal(stepped, batch["series"].output)
    header = (tmp_path / "estimates.csv").read_text().splitlines()[0]
    documented = re.search(r"# estimates\.csv: (\S+)", LIBRARY_GUIDE.read_text())
    assert documented and documented.group(1) == header  # the guide's comment is the header


#: development history that belongs in CHANGELOG.md, not in pages or code
HISTORY = re.compile(
    r"\b(this|previous|earlier|last|next) session\b|\bsessions? \d+\b|\bbefore session\b"
    r"|\bissue ?#?\d+\b|\bpreviously\b|\bearlier (core|version|build|release)s?\b"
    r"|\bformer name\b|\bused to (be|give|say|exit|write|read|run)\b",
    re.IGNORECASE,
)

#: more history, in the tests' docstrings and comments: what a test guards against is
#: said as what the code does not do, not as what it did
TEST_HISTORY = re.compile(
    r"\bno longer\b(?! than)|\banymore\b|\b(was|were) an internal error\b"
    r"|\((it|they) (was|were|said|gave|took|ran|raised|printed|crashed|stopped|ended)\b",
    re.IGNORECASE,
)

#: "now" in a test's docstring (its comments narrate the steps: "buffer 0 now holds")
DOCSTRING_NOW = re.compile(r"\bnow\b(?! and then)", re.IGNORECASE)


def _history_lines(path: Path) -> list[tuple[int, str]]:
    """The lines of ``path`` that hold development history, ``(number, text)``: any line
    of a page, the code or the tools; of a test module its docstrings and comments
    alone (its strings and patterns may spell the history out, as :data:`HISTORY`
    does)."""
    text = path.read_text()
    test_module = path.parent == ROOT / "tests"
    patterns = (HISTORY, TEST_HISTORY, DOCSTRING_NOW) if test_module else (HISTORY,)
    if not any(p.search(text) for p in patterns):
        return []  # (a line's match is one in the whole text: most files need no more)
    lines = text.splitlines()
    if not test_module:
        return [(n, line) for n, line in enumerate(lines, 1) if HISTORY.search(line)]
    found = {
        token.start[0]
        for token in tokenize.generate_tokens(io.StringIO(text).readline)
        if token.type == tokenize.COMMENT
        and (HISTORY.search(token.string) or TEST_HISTORY.search(token.string))
    }
    for node in ast.walk(ast.parse(text)):
        if (
            isinstance(node, ast.Expr)
            and isinstance(node.value, ast.Constant)
            and isinstance(node.value.value, str)
        ):
            found |= {
                n
                for n in range(node.lineno, (node.end_lineno or node.lineno) + 1)
                if any(p.search(lines[n - 1]) for p in (HISTORY, TEST_HISTORY, DOCSTRING_NOW))
            }
    return [(n, lines[n - 1]) for n in sorted(found)]


def test_no_development_history_in_docs_or_source():
    """The README, the documentation site, the code, the tools and the tests' docstrings
    and comments state what is true: no development history (:data:`HISTORY`,
    :data:`TEST_HISTORY`, :data:`DOCSTRING_NOW`; the history is CHANGELOG.md's)."""
    paths = [
        ROOT / "README.md",
        *(ROOT / "docs").rglob("*.md"),
        *(ROOT / "src").rglob("*.py"),
        *(ROOT / "tools").rglob("*.py"),
        *(ROOT / "tests").glob("*.py"),
        *(ROOT / "csrc").glob("*.[ch]pp"),
    ]
    found = [
        f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
        for path in paths
        for number, line in _history_lines(path)
    ]
    assert not found, "\n".join(found)


#: What the repository's root holds: a file or folder beside these (a command's output
#: written into the checkout and committed with it) is a stray
ROOT_ENTRIES = frozenset({
    ".ci", ".gitignore", "CHANGELOG.md", "CMakeLists.txt", "CONTRIBUTING.md", "LICENSE",
    "README.md", "csrc", "docs", "firmware", "mkdocs.yml", "pyproject.toml", "src",
    "tests", "tools",
})  # fmt: skip


def test_the_repository_root_holds_no_stray_files() -> None:
    """Every file git tracks lies in one of the root's own entries (:data:`ROOT_ENTRIES`):
    a recording or an estimate written into the checkout (``rod tendon -o t1``) and
    committed with it is caught. Skipped outside a git checkout (an unpacked source
    archive)."""
    if not (ROOT / ".git").exists() or shutil.which("git") is None:
        pytest.skip("not a git checkout")
    listed = _run("git", "ls-files", "-z")
    assert listed.returncode == 0, listed.stderr
    stray = sorted({f.split("/")[0] for f in listed.stdout.split("\0") if f} - ROOT_ENTRIES)
    assert not stray, f"tracked at the repository's root beside its own entries: {stray}"


def test_the_suites_interpreters_share_one_bytecode_folder() -> None:
    """Under PYTHONDONTWRITEBYTECODE the suite's interpreters (a process that loads
    tests/conftest.py and a command it starts) write their bytecode into the session's
    folder, not nowhere and not beside the sources, and the folder is removed at the
    run's end: checked in a fresh interpreter that sets the variable (CI does not), and
    in this run where it was set."""
    shown = "import sys; print(sys.pycache_prefix, sys.dont_write_bytecode)"
    code = (
        "import os, subprocess, sys\n"
        "sys.path.insert(0, 'tests')\n"
        "import conftest\n"
        "folder = os.environ['CONTINUUM_MHE_TEST_PYCACHE']\n"
        f"child = subprocess.run([sys.executable, '-c', {shown!r}], capture_output=True,\n"
        "                       text=True, check=True).stdout.split()\n"
        "print(folder, os.path.isdir(folder), 'PYTHONDONTWRITEBYTECODE' in os.environ,\n"
        "      sys.pycache_prefix == folder, sys.dont_write_bytecode, *child)\n"
        "conftest.pytest_unconfigure()\n"
        "print(os.path.isdir(folder))\n"
    )
    session = ("CONTINUUM_MHE_TEST_PYCACHE", "PYTHONPYCACHEPREFIX")
    env = {k: v for k, v in os.environ.items() if k not in session}
    r = subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT, env={**env, "PYTHONDONTWRITEBYTECODE": "1"},
        capture_output=True, text=True, check=False, timeout=600,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    made, removed = r.stdout.splitlines()
    folder, *rest = made.split()
    assert Path(folder).name.startswith("continuum-mhe-tests-pyc-")
    assert rest == ["True", "False", "True", "False", folder, "False"], made
    assert removed == "False"
    folder = os.environ.get("CONTINUUM_MHE_TEST_PYCACHE", "")
    if folder:  # this run's own
        assert "PYTHONDONTWRITEBYTECODE" not in os.environ and Path(folder).is_dir()
        assert (sys.pycache_prefix, sys.dont_write_bytecode) == (folder, False)
        assert _run(sys.executable, "-c", shown).stdout.split() == [folder, "False"]
