"""The command-line package: one command per module, the live loop imported only with the
parser, and the library's refusals carrying the argument that the command names by its flag."""

from __future__ import annotations

import pickle
import subprocess
import sys
from pathlib import Path

import pytest

import delaytrack.cli
from delaytrack._cli_options import OptionParser
from delaytrack._spec import SpecError
from delaytrack._validation import ArgumentError
from delaytrack.analysis import design_gains, razumikhin_bound
from delaytrack.cli._parser import COMMANDS, build_parser
from delaytrack.cli._usage import flagged
from delaytrack.experiments import empirical_margin
from delaytrack.scenario import ScenarioError, load_builtin
from delaytrack.sweeps import SweepError
from delaytrack.sweeps.executors import checked_workers

PACKAGE = Path(delaytrack.cli.__file__).parent


def _command_modules() -> set[str]:
    """The command modules: every module of the package whose name has no leading ``_``."""
    return {path.stem for path in PACKAGE.glob("*.py") if not path.stem.startswith("_")}


# ---- the layout ---------------------------------------------------------------------------------


def test_every_command_module_is_in_the_parser():
    assert {module.__name__.rpartition(".")[2] for module in COMMANDS} == _command_modules()


@pytest.mark.parametrize("module", COMMANDS, ids=lambda module: module.__name__)
def test_a_command_module_adds_exactly_one_command_with_its_handler(module):
    commands = OptionParser(prog="delaytrack").add_subparsers()
    module.add_command(commands)
    assert len(commands.choices) == 1, f"{module.__name__} adds {sorted(commands.choices)}"
    (command,) = commands.choices.values()
    assert command.get_default("handler") is module.run


def test_the_parser_holds_the_modules_commands_and_live_only():
    parser = build_parser()
    (commands,) = (action for action in parser._actions if action.dest == "command")
    single = OptionParser(prog="delaytrack").add_subparsers()
    for module in COMMANDS:
        module.add_command(single)
    assert set(commands.choices) == {*single.choices, "live"}


def test_importing_the_command_line_does_not_import_the_live_loop():
    modules = ", ".join(f"delaytrack.cli.{name}" for name in sorted(_command_modules()))
    code = (
        f"import sys, delaytrack.cli, {modules}\n"
        "assert 'delaytrack.live' not in sys.modules, sorted(m for m in sys.modules if 'live' in m)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr


# ---- errors that carry their argument ------------------------------------------------------------


def test_an_argument_error_names_each_argument_as_the_caller_does():
    error = ArgumentError("resolution", "must be smaller than $upper; got $up", ("upper",))
    assert str(error) == "resolution must be smaller than upper; got $up"
    flags = {"resolution": "--resolution", "upper": "--upper"}
    assert error.spelled(flags) == "--resolution must be smaller than --upper; got $up"
    again = pickle.loads(pickle.dumps(error))  # as from a worker process
    assert (again.argument, again.spelled(flags), str(again)) == (
        "resolution",
        error.spelled(flags),
        str(error),
    )


def test_the_library_says_which_argument_is_wrong():
    with pytest.raises(ArgumentError) as refused:
        razumikhin_bound(-1.0, 1.0)
    assert refused.value.argument == "K1"
    with pytest.raises(ArgumentError) as refused:
        razumikhin_bound(1.0, 1.0, 1.0, beta=1e308)
    assert refused.value.argument == "beta"
    with pytest.raises(ArgumentError) as refused:
        design_gains(gain_bound=1.0, min_bandwidth=2.0)
    assert refused.value.argument == "min_bandwidth"
    assert "above gain_bound = 1; raise gain_bound" in str(refused.value)
    with pytest.raises(ArgumentError) as refused:
        empirical_margin(load_builtin("two_link_margins"), threshold=1.0, upper=0.5, resolution=0.6)
    assert refused.value.argument == "resolution"
    with pytest.raises(SweepError) as refused:  # still a SweepError, as documented
        checked_workers(10**6)
    assert isinstance(refused.value, ArgumentError) and refused.value.argument == "workers"


def test_a_scenario_error_about_a_key_carries_the_key():
    with pytest.raises(ScenarioError) as refused:
        load_builtin("two_link_S1").replace(duration=1.0001)
    assert (refused.value.key, refused.value.problem) == (
        "duration",
        str(refused.value).removeprefix("scenario key 'duration' "),
    )
    assert SpecError("a table").key is None


def test_the_command_line_names_the_flag_and_keeps_the_librarys_words():
    error = ArgumentError("K1", "must be > 0; got [[-1.0]]")
    assert str(flagged(error, {"K1": "--k1"}, given={"--k1": "-1"})) == (
        "--k1 must be > 0; got [[-1.0]] (got --k1 -1)"
    )
    said = ArgumentError("beta", "must be > 0; got -0.5")  # ends with what was given: once
    assert str(flagged(said, {"beta": "--beta"}, given={"--beta": "-0.5"})) == (
        "--beta must be > 0; got -0.5"
    )
    assert str(flagged(error, {"K2": "--k2"})) == str(error)  # another argument: as it is
    key = SpecError.of_key("duration", "must be > 0 (seconds); got -1")
    assert str(flagged(key, keys={"duration": "--duration"})) == (
        "--duration must be > 0 (seconds); got -1"
    )
    assert str(flagged(key, {"duration": "--duration"})) == str(key)  # keys only by keys=


def test_the_paper_job_refuses_a_duration_off_its_controller_period_before_writing(tmp_path):
    from delaytrack.experiments import paper
    from delaytrack.jobs.paper import reproduce

    with pytest.raises(ArgumentError) as refused:
        reproduce(tmp_path / "out", duration=1.5 * paper.T_C, progress=False)
    assert refused.value.argument == "duration"
    assert f"'T_c' = {paper.T_C:g} s" in str(refused.value)
    assert not (tmp_path / "out").exists()
