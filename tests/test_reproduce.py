"""The main job (``delaytrack reproduce``), the README's promises and the example, end to end."""

from __future__ import annotations

import base64
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pandas as pd
import pytest

from delaytrack.cli import main
from delaytrack.scenario import Scenario

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_reproduce_smoke(tmp_path, capsys):
    args = ["reproduce", "--job", "two-link", "--out", str(tmp_path), "--duration", "1", "--quiet"]
    assert main(args) == 0
    printed = capsys.readouterr().out
    folder = tmp_path / "two-link"
    assert "report.html" in printed

    summary = pd.read_csv(folder / "summary.csv")
    assert list(summary[["scenario", "controller"]].itertuples(index=False, name=None)) == [
        ("S1", "arolc"),
        ("S1", "outer-loop"),
        ("S3", "arolc"),
        ("S3", "outer-loop"),
    ]
    metrics = ("ae_q1", "ae_q2", "rms_q1", "rms_q2", "max_q1", "max_q2")
    for column in (*(f"{name}_rad" for name in metrics), "tv_Nm", "t_stop_s", "status"):
        assert column in summary.columns
    assert (summary["status"] == "ok").all()
    assert (summary["ae_q1_rad"] > 0).all()

    check = pd.read_csv(folder / "dt_check.csv")
    assert len(check) == 4 and (check["max_relative_change"] < 0.01).all()
    assert "ae_q1_rad" in check.columns  # every table with its units

    for case in ("S1", "S3"):
        for controller in ("arolc", "outer-loop"):
            frame = pd.read_parquet(folder / "trajectories" / f"{case}_{controller}.parquet")
            assert len(frame) == 501 and frame["t_s"].iloc[-1] == pytest.approx(1.0)
    for name in ("error_S1", "error_S3", "c_hat", "delay"):
        for ext in ("png", "svg"):
            assert (folder / "figures" / f"{name}.{ext}").stat().st_size > 1000
    for path in (folder / "scenarios").glob("*.toml"):
        assert Scenario.from_toml(path).duration == 1.0

    report = (folder / "report.html").read_text()
    assert "0.12487" in report and "h_m" in report
    images = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', report)
    assert len(images) >= 4
    assert base64.b64decode(images[0])[:8] == b"\x89PNG\r\n\x1a\n"
    assert "<script" not in report and 'src="http' not in report and "<link" not in report
    assert "20 % below the truth" in report


def test_reproduce_rejects_a_bad_duration(tmp_path, capsys):
    assert main(["reproduce", "--out", str(tmp_path), "--duration", "-1", "--quiet"]) == 2
    assert "--duration must be a positive number of seconds" in capsys.readouterr().err
    args = ["reproduce", "--job", "two-link", "--out", str(tmp_path), "--duration", "0.0015"]
    assert main([*args, "--quiet"]) == 2
    assert "must be a positive integer multiple of 'T_c'" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (
            ["--job", "two-link", "--scheduler", "tcp://127.0.0.1:1"],
            "--scheduler does not apply to --job two-link; it applies to --job paper, "
            "robustness or decision",
        ),
        (["--job", "margins", "--size", "full"], "--size does not apply to --job margins"),
        (["--job", "two-link", "--no-contact"], "--no-contact does not apply to --job two-link"),
        (["--job", "robustness", "--no-dt-check"], "--no-dt-check does not apply"),
        (["--job", "decision", "--no-robustness"], "--no-robustness does not apply"),
        (
            ["--no-robustness", "--scheduler", "local-cluster"],
            "--scheduler sets the robustness and decision studies, which this paper job does "
            "not run",
        ),
        (["--no-robustness", "--size", "full"], "--size sets the robustness and decision"),
    ],
)
def test_reproduce_refuses_a_flag_its_job_would_ignore(tmp_path, capsys, flags, message):
    """A flag that changes nothing in the job asked for was ignored without a word (an
    unreachable scheduler address was taken, the job then ran on this machine)."""
    assert main(["reproduce", "--out", str(tmp_path / "out"), *flags, "--quiet"]) == 2
    error = capsys.readouterr().err
    assert error.startswith("error: ") and error.count("\n") == 1 and message in error, error
    assert not (tmp_path / "out").exists()


def test_readme_first_screen_introduces():
    """Its first screen says what this is and for whom, the two commands, the install with its
    extras (each one pyproject.toml declares) and starts the example on a plant of one's own."""
    text = (ROOT / "README.md").read_text()
    first_screen = "\n".join(text.splitlines()[:40])
    assert first_screen.startswith("# delaytrack\n")
    assert "For control engineers and researchers" in first_screen
    commands = [line.split("#")[0].strip() for line in first_screen.splitlines()]
    assert commands.index("make reproduce") + 1 == commands.index("make test")
    assert "pip install -e ." in commands and "```python" in commands
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]
    named = set(re.findall(r"\[(\w+)\]", first_screen.split("```python")[0]))
    assert named == {"tutorial", "mujoco", "dask", "live", "docs", "test"} == set(extras)


def test_readme_terms_are_defined_at_first_use():
    """Each term of the paper is explained where the README first uses it: the term's first
    occurrence lies in its definition."""
    text = " ".join((ROOT / "README.md").read_text().split())
    for term, definition in [
        ("AROLC", "**AROLC**, the adaptive-robust outer-loop controller of Roy & Kar"),
        ("`h_m`", "**`h_m`**, the largest delay for which the paper's Theorem 1 certifies it"),
        ("`Δu`", "adaptive-robust term **`Δu`**, whose gain `ĉ` adapts online"),
        ("AE", "AE (mean absolute error)"),
        ("S1", "**S1** (`h(t) = 20 + 80 |sin t|` ms)"),
        ("S2", "**S2** (5 + 120 |sin 0.1t| ms)"),
        ("PCON", "**PCON** (used for S1, S2 and told the true delay)"),
        ("PCONf", "**PCONf** (used for S3, S4, which assumes a constant known delay"),
        ("`h̄`", "assumes a constant known delay **`h̄`**"),
        ("consistent path", "the **consistent path** (the paper's circle"),
        ("literal path", "the **literal path** (as printed)"),
    ]:
        assert definition in text, term
        assert text.index(term) == text.index(definition) + definition.index(term), term


@pytest.mark.slow
def test_custom_plant_example_runs(tmp_path):
    done = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "custom_plant.py"), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert (
        "AROLC: status ok" in done.stdout and "certified delay bound h_m = 124.9 ms" in done.stdout
    )
    assert (tmp_path / "pendulum_error.png").is_file()


def _readme_blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", (ROOT / "README.md").read_text(), re.S)


def test_readme_python_examples_run(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    blocks = _readme_blocks("python")
    assert len(blocks) >= 3
    for number, block in enumerate(blocks):
        # Run as a script is: a kernel is then the one the docs pages define with the same code
        # (same name), whose engine one of them compiles and the other loads from disk.
        exec(compile(block, f"README.md python block {number}", "exec"), {"__name__": "__main__"})
    out = capsys.readouterr().out
    assert "(2, 2501, 2) ['ok', 'ok']" in out and "0.12487" in out
    assert Scenario.from_toml(tmp_path / "my_scenario.toml").duration == 2.0
    assert (tmp_path / "error_S1.png").stat().st_size > 0
    # The first example, a plant of one's own: it tracks, within Theorem 1's bound, and draws
    # the figure that scripts/readme_figure.py copies to where the README shows it from.
    assert re.search(r"^0\s+ok\s+20\.0\s+0\.01\d+", out, re.M), out
    assert "0.01314" in out
    assert (tmp_path / "joint.png").stat().st_size > 0
    assert "(docs/images/readme_joint.png)" in (ROOT / "README.md").read_text()
    assert (ROOT / "docs" / "images" / "readme_joint.png").stat().st_size > 0


def test_readme_user_component_tables_are_the_shipped_examples():
    _, *blocks = _readme_blocks("toml")
    examples = Path(__file__).resolve().parents[1] / "examples" / "user_arm"
    for block, name in zip(blocks, ["arm_S1.toml", "arm_congested.toml"], strict=True):
        shown = tomllib.loads(block)
        shipped = tomllib.loads((examples / name).read_text())
        assert shown == {table: shipped[table] for table in shown}


def test_readme_scenario_file_is_valid():
    block, *_ = _readme_blocks("toml")
    scenario = Scenario.from_dict(tomllib.loads(block))
    built = scenario.build()
    assert built.delay.h_max == pytest.approx(0.125)
    assert built.controller.K2.tolist() == [[1.0, 0.0], [0.0, 1.5]]
