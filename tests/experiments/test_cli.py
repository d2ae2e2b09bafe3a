"""``gva``'s parser: what each command imports, defaults read from the settings dataclasses,
and bad task files refused in one line."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from gva_cli import gva

from experiments.cli import build_parser, main
from experiments.table2.settings import ReproduceSimSettings
from experiments.table3.settings import ReproduceRealSettings
from harness.inputs.collector import CollectSettings
from harness.inputs.trial_settings import TrialSettings
from harness.jobs import Executor, ExecutorKind
from perception.learning.train import TrainConfig
from perception.learning.validation import CheckConfig
from sim.trials.closed_loop.loop_settings import Loop, LoopSettings
from sim.world.sensor import SensorKind

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
    (["judge", "runs/a"], set()),
    (["reproduce", "real", "--out", "runs/x"], {"pinocchio", "torch"}),
])
def test_a_command_imports_only_what_it_needs(argv, allowed):
    assert _loaded_after(argv) <= allowed


def _parsed(*argv: str) -> dict[str, object]:
    return vars(build_parser().parse_args(list(argv)))


def test_the_defaults_are_the_settings_dataclasses_defaults():
    sim = _parsed("reproduce", "sim", "--out", "x")
    for field in dataclasses.fields(ReproduceSimSettings):
        if field.name not in ("executor", "model_configs"):
            assert sim[field.name] == getattr(ReproduceSimSettings(), field.name), field.name
    real = _parsed("reproduce", "real", "--out", "x")
    assert sim["model_config"] == real["model_config"] == []  # the settings' () of files
    assert ReproduceSimSettings().model_configs == ReproduceRealSettings().model_configs == ()
    for field in dataclasses.fields(ReproduceRealSettings):
        if field.name not in ("check", "executor", "model_configs", "loop"):
            value = SensorKind(real["sensor"]) if field.name == "sensor" else real[field.name]
            assert value == getattr(ReproduceRealSettings(), field.name), field.name
    assert real["holdout"] == ReproduceRealSettings().check.holdout
    for parsed in (real, _parsed("trials", "--out", "x")):  # --loop, --replan-hz
        assert LoopSettings(Loop(parsed["loop"]), parsed["replan_hz"]) == LoopSettings()
    assert ReproduceRealSettings().loop == TrialSettings("oracle", "single").loop
    for parsed in (sim, real, _parsed("trials", "--out", "x")):
        assert Executor(ExecutorKind(parsed["executor"]), parsed["ray_address"]) == Executor()
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
                       min_expected_success=train["check_min_expected"],
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


BAD_TASK_FILES = {  # name: (file contents, what the one line must name besides the file)
    "count-1e18": (b'name = "huge"\n[objects]\ncount = 1000000000000000000\n',
                   ("objects.count = 1000000000000000000", "an integer in [1, 12]")),
    "100-at-spacing-0": (b'name = "heap"\n[objects]\ncount = 100\n[placement]\n'
                         b"min_spacing_m = 0\n", ("objects.count = 100", "an integer in [1, 12]")),
    "nan-spacing": (b'name = "nan"\n[placement]\nmin_spacing_m = nan\n',
                    ("placement.min_spacing_m = nan", "a distance in [0, 0.5] m")),
    "sides-on-one-side": (b'name = "left-only"\n[objects]\nchoose = "same_type"\ncount = 2\n'
                          b'[targets]\nselect = "condition"\n[condition]\nkind = "side"\n'
                          b"[placement]\nsides = true\ny_m = [0.05, 0.15]\n",
                          ("placement.y_m = [0.05, 0.15]", "room for an object on each side")),
    "binary": (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\xff\xfe",
               ("'not UTF-8 text'", "a TOML text file in UTF-8")),
    "not-toml": (b"name: sponge-task\ncount: 2\n", ("'not valid TOML'", "TOML (")),
}
COMMANDS = {"trials": ["trials", "--n", "1"],
            "collect": ["collect", "--scene", "yumi", "--size", "1"]}


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("case", BAD_TASK_FILES)
def test_a_bad_task_file_is_refused_in_one_line_with_status_2(tmp_path, command, case):
    contents, named = BAD_TASK_FILES[case]
    task = tmp_path / f"{case}.toml"
    task.write_bytes(contents)
    out = tmp_path / "out"
    status, stdout, stderr = gva(*COMMANDS[command], "--task", task, "--out", out)
    assert status == 2, stderr
    assert stderr.endswith("\n") and stderr.count("\n") == 1, stderr  # one line, no progress bar
    assert stderr.startswith(f"gva {command}: error: task") and f"{case}.toml" in stderr
    assert all(part in stderr for part in named), stderr
    assert "Traceback" not in stderr and not stdout and not out.exists()


def test_a_bad_task_file_is_refused_within_a_timeout_not_after_a_hang(tmp_path):
    # Before the count bound, this file ran for minutes; here a hang fails the test at the
    # timeout instead of stalling the suite (the generous limit is no timing measurement).
    task = tmp_path / "heap.toml"
    task.write_bytes(BAD_TASK_FILES["100-at-spacing-0"][0])
    done = subprocess.run(
        [sys.executable, "-m", "experiments.cli", "trials", "--task", str(task), "--n", "1",
         "--out", str(tmp_path / "out")],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "objects.count = 100" in done.stderr


def test_a_bad_phrase_file_is_refused_in_one_line_naming_its_line(tmp_path):
    phrases = tmp_path / "mine.tsv"
    phrases.write_text("the absorbent scourer\tsponge\nthe atomiser spray_bottle\n")
    out = tmp_path / "out"
    status, stdout, stderr = gva("trials", "--task", "selected-type-text", "--phrases", phrases,
                                 "--n", "1", "--out", out)
    assert status == 2 and not stdout, stderr
    assert stderr.count("\n") == 1 and "phrases mine.tsv line 2" in stderr, stderr
    assert "phrase<TAB>target" in stderr and not out.exists()


@pytest.mark.parametrize("argv", [
    ("reproduce", "real", "--out", "{out}", "--variants", ""),
    ("reproduce", "real", "--out", "{out}", "--variants", ",,"),
    ("reproduce", "real", "--out", "{out}", "--variants", "dark,,block"),
    ("reproduce", "real", "--out", "{out}", "--tasks", "single,"),
    ("reproduce", "sim", "--out", "{out}", "--models", ""),
    ("trials", "--model", "oracle", "--task", "single", "--out", "{out}", "--variant", "dark",
     "--variant", "block"),
    ("collect", "--scene", "yumi", "--task", "single", "--size", "1", "--out", "{out}/d.gva",
     "--variant", "dark", "--variant", "dark"),
])
def test_an_empty_name_or_an_option_given_twice_is_refused_not_dropped(tmp_path, argv):
    # issue 77: `--variants ''` and `,,` ran no variants without a word, and `--variant dark
    # --variant block` ran block alone
    out = tmp_path / "run"
    status, _, stderr = gva(*(a.format(out=out) for a in argv))
    assert status == 2 and ("none empty" in stderr or "given twice" in stderr), stderr
    assert not out.exists()  # refused before anything is written
