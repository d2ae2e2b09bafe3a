"""Options declared once (issue 78): the command line of a run's settings parses back to them."""

import argparse
import shlex
from pathlib import Path

import pytest

from experiments.cli import build_parser
from experiments.commands.options import CommandLine, Option, text
from experiments.table2.options import SIM
from experiments.table2.settings import ReproduceSimSettings
from experiments.table3.options import REAL
from experiments.table3.settings import ReproduceRealSettings
from perception.learning.validation import CheckConfig
from sim.trials.closed_loop.loop_settings import Loop, LoopSettings
from sim.world.sensor import SensorKind


def parsed(line: str, table: CommandLine, settings: type):
    """The settings ``line`` (``gva ...``) gives, through the parser and the table."""
    args = build_parser().parse_args(shlex.split(line)[1:])
    assert args.out == Path("o")
    return settings(**table.keywords(args, settings))


@pytest.mark.parametrize("keywords", [
    {}, {"seeds": 2, "seed": 3}, {"variants": ()}, {"variants": ("block",)},
    {"balance_types": False, "sensor": SensorKind.IDEAL, "robot": "panda", "world": "dark"},
    {"loop": LoopSettings(Loop.CLOSED, 2.5), "train_threads": 2},
    {"check": CheckConfig(holdout=0.0), "gif_trials": 0, "use_failed_checkpoints": True},
    {"tasks": ("single",), "models": ("kqv", "fcn"), "n": 2, "demos": 3, "steps": 4},
    {"randomised_scenes": 200, "world": "varied-held-out"},
])
def test_a_real_command_line_gives_back_its_settings(keywords):
    settings = ReproduceRealSettings(**keywords)
    assert parsed(settings.command(Path("o")), REAL, ReproduceRealSettings) == settings


@pytest.mark.parametrize("keywords", [
    {}, {"seeds": 1, "seed": 4, "steps": 5}, {"models": ("kqv",), "sizes": (4, 20)},
    {"tasks": ("multiple",), "test_scenes": 3, "scene": "yumi", "sensor": SensorKind.IDEAL},
])
def test_a_sim_command_line_gives_back_its_settings(keywords):
    settings = ReproduceSimSettings(**keywords)
    assert parsed(settings.command(Path("o")), SIM, ReproduceSimSettings) == settings


def test_the_defaults_are_the_settings_fields():
    assert parsed("gva reproduce real --out o", REAL, ReproduceRealSettings) == \
        ReproduceRealSettings()
    assert parsed("gva reproduce sim --out o", SIM, ReproduceSimSettings) == ReproduceSimSettings()


def test_an_order_that_misses_a_written_option_is_refused():
    rows = (Option("--seed", help="h"), Option("--n", help="h"),
            Option("--workers", help="h", shown="never"))
    CommandLine("gva x", rows, order=("--n", "--seed"))
    with pytest.raises(ValueError, match="order"):
        CommandLine("gva x", rows, order=("--seed",))
    with pytest.raises(ValueError, match="order"):
        CommandLine("gva x", rows, order=("--seed", "--n", "--workers"))


def test_a_switch_on_by_default_is_turned_off_by_its_no_flag():
    parser = argparse.ArgumentParser()
    Option("--balance-types", help="on? ({default})").add_to(parser, True)
    assert parser.parse_args(["--no-balance-types"]).balance_types is False
    assert "(on)" in parser.format_help()


def test_values_are_written_as_the_command_line_takes_them():
    assert [text(v) for v in (("a", "b"), (4, 20), 0.25, 5.0, SensorKind.D435, True, 3)] == \
        ["a,b", "4,20", "0.25", "5", "d435", "on", "3"]
