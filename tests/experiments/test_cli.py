"""``gva``'s parser: what each command imports, and defaults read from the settings dataclasses."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from experiments.cli import build_parser, main
from experiments.table2.settings import ReproduceSimSettings
from experiments.table3.settings import ReproduceRealSettings
from perception.train import TrainConfig
from perception.validation import CheckConfig
from sim.trials.collector import CollectSettings
from sim.trials.run_loop import TrialSettings

ROOT = Path(__file__).resolve().parents[2]


def _loaded_after(argv: list[str]) -> set[str]:
    """The heavy libraries a fresh interpreter holds after parsing ``gva ARGV``."""
    script = textwrap.dedent(f"""
        import sys
        from experiments.cli import build_parser
        try:
            build_parser().parse_args({argv!r})
        except SystemExit:
            pass
        loaded = [k for k in ("torch", "pinocchio", "matplotlib") if k in sys.modules]
        print("loaded:", *loaded)
    """)
    done = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True,
                          text=True, check=True)
    return set(done.stdout.splitlines()[-1].split()[1:])


@pytest.mark.parametrize(("argv", "allowed"), [
    (["--help"], set()),
    (["reproduce", "--help"], set()),
    (["trials", "--out", "runs/x"], {"pinocchio"}),
    (["compare", "runs/a", "runs/b"], set()),
    (["reproduce", "real", "--out", "runs/x"], {"pinocchio", "torch"}),
])
def test_a_command_imports_only_what_it_needs(argv, allowed):
    assert _loaded_after(argv) <= allowed


def _parsed(*argv: str) -> dict[str, object]:
    return vars(build_parser().parse_args(list(argv)))


def test_the_defaults_are_the_settings_dataclasses_defaults():
    sim = _parsed("reproduce", "sim", "--out", "x")
    for field in dataclasses.fields(ReproduceSimSettings):
        assert sim[field.name] == getattr(ReproduceSimSettings(), field.name), field.name
    real = _parsed("reproduce", "real", "--out", "x")
    for field in dataclasses.fields(ReproduceRealSettings):
        if field.name != "check":
            assert real[field.name] == getattr(ReproduceRealSettings(), field.name), field.name
    assert real["holdout"] == ReproduceRealSettings().check.holdout
    trials = _parsed("trials", "--out", "x")
    assert (trials["n"], trials["seed"]) == (TrialSettings.n, TrialSettings.seed)
    assert trials["obstacles"] == TrialSettings.obstacles.value
    collect = _parsed("collect", "--scene", "yumi", "--task", "single", "--size", "1",
                      "--out", "x")
    assert collect["seed"] == CollectSettings.seed
    assert collect["stream"] == CollectSettings.stream.name.lower()
    train = _parsed("train", "--model", "kqv", "--data", "d", "--out", "x")
    assert TrainConfig(steps=train["steps"], batch_size=train["batch_size"],
                       seed=train["seed"], threads=train["threads"]) == TrainConfig()
    assert CheckConfig(holdout=train["holdout"], limit_cm=train["check_limit_cm"],
                       attempts=train["attempts"]) == CheckConfig()


def test_help_states_the_defaults_of_the_dataclasses(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["reproduce", "real", "--help"])
    shown = capsys.readouterr().out
    assert f"trials per model and task ({TrialSettings.n})" in shown
    assert f"optimiser steps of training ({TrainConfig.steps})" in shown


def test_ctrl_c_prints_the_command_that_resumes(tmp_path, capsys, monkeypatch):
    def interrupted(settings, out, **options):
        raise KeyboardInterrupt

    monkeypatch.setattr("experiments.commands.trials.run_trials", interrupted)
    status = main(["trials", "--n", "2", "--out", str(tmp_path / "my run"), "--no-progress"])
    assert status == 130
    assert capsys.readouterr().err == (f"gva trials: interrupted; resume with: gva trials --n 2 "
                                       f"--out '{tmp_path / 'my run'}' --no-progress\n")
