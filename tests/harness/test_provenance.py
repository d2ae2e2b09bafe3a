"""What made a result: every session that worked on a run folder, in run.json and the summary."""

from __future__ import annotations

import json
import subprocess
from importlib import metadata
from pathlib import Path

from harness.inputs.trial_settings import TrialSettings
from harness.provenance import ROOT, git_revision, provenance
from harness.run_loop import run_trials
from perception.files import file_sha256
from sim.tasks.task_toml import TASK_FILES


def test_run_json_and_the_summary_say_what_made_the_trials(tmp_path):
    run_trials(TrialSettings("oracle", "single", n=1), tmp_path, progress=False)
    run_trials(TrialSettings("oracle", "single", n=2), tmp_path, progress=False)  # resumed
    sessions = json.loads((tmp_path / "run.json").read_text())["provenance"]
    assert len(sessions) == 2  # the first run and the one that resumed it
    summary = json.loads((tmp_path / "summary.json").read_text())
    made = summary["provenance"]
    assert made == sessions[-1]
    assert made["versions"]["torch"] == metadata.version("torch")
    assert made["versions"]["pybullet"] == metadata.version("pybullet")
    assert set(made["versions"]) == {"gva", "torch", "pybullet", "pin", "ruckig", "numpy"}
    assert made["sha256"]["task_file"] == file_sha256(TASK_FILES / "single.toml")
    assert made["git"] == git_revision() and made["command"]


def test_a_run_names_the_commit_of_the_checkout_it_runs_from():
    # harness/ moved one level up once and the lookup kept its old depth: every run then
    # recorded "git": null. The checkout these tests run from is the project's (CI: a fresh
    # clone), so its own HEAD is what a run must name.
    checkout = Path(__file__).resolve().parents[2]
    assert (checkout / "pyproject.toml").is_file() and ROOT == checkout
    head = subprocess.run(["git", "-C", str(checkout), "rev-parse", "HEAD"], capture_output=True,
                          text=True, check=False)
    if head.returncode != 0:  # an exported tree (no .git): nothing to name, and None says so
        assert git_revision() is None
        return
    revision = git_revision()
    assert revision is not None and revision["commit"] == head.stdout.strip()
    assert provenance()["git"] == revision


def test_a_checkpoints_files_are_hashed(tmp_path):
    folder = tmp_path / "ckpt"
    folder.mkdir()
    (folder / "weights.safetensors").write_bytes(b"w")
    (folder / "config.json").write_text("{}")
    session = provenance({"checkpoint_weights": folder / "weights.safetensors",
                          "checkpoint_config": folder / "config.json", "task_file": None})
    assert session["sha256"] == {
        "checkpoint_weights": "50e721e49c013f00c62cf59f2163542a9d8df02464efeb615d31051b0fddc326",
        "checkpoint_config": "44136fa355b3678a1146ad16f7e8649e94fb4fc21fe77e8310c060f61caaff8a",
        "task_file": None}


def test_the_cpu_kernels_of_torch_are_recorded_where_torch_is_loaded():
    import torch

    assert provenance()["torch_cpu_capability"] == torch.backends.cpu.get_cpu_capability()
