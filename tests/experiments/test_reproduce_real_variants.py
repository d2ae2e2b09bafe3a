"""A run's variants: each labelled by its own name, and a refused one writes nothing (issue 77)."""

from __future__ import annotations

import pytest
from gva_cli import gva

from experiments.table3.settings import ReproduceRealSettings
from sim.errors import InvalidInputError

TINY = ["--tasks", "single", "--demos", "2", "--n", "2", "--steps", "3", "--workers", "1",
        "--no-progress"]


def test_a_variant_is_labelled_by_its_own_name_or_refused(tmp_path):
    # issue 77: `--variants dark,mine/dark.toml` ran one `single-dark` folder labelled "darker
    # light"; a file called plain.toml ran trials no report showed, open-loop.toml wrote into
    # the open-loop comparison's folder
    def variant_file(relative: str) -> str:
        path = tmp_path / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("[lighting]\nbrightness = 0.7\n")
        return str(path)

    for variants, message in (
            ((variant_file("mine/dark.toml"),), r"variant = '.*dark.toml' is not allowed: a "
                                                r"variant file whose name is not a built-in "
                                                r"variant's \(dark is one\)"),
            (("dark", variant_file("a/dim.toml"), variant_file("b/dim.toml")),
             r"variants = .* variants of distinct names"),
            ((variant_file("plain.toml"),), r"none called plain or open-loop"),
            ((variant_file("open-loop.toml"),), r"none called plain or open-loop")):
        with pytest.raises(InvalidInputError, match=message):
            ReproduceRealSettings(variants=variants)
    mine = ReproduceRealSettings(variants=("dark", variant_file("c/dim.toml")))
    assert {s.variant for s in mine.trial_sets()} >= {"dark", variant_file("c/dim.toml")}
    assert set(mine.shared_identity()["variants"]) == {"dark", "dim"}


def test_a_variant_the_task_refuses_stops_the_run_before_its_folder_is_written(tmp_path):
    # issue 77: a refused run left run.json behind, and the corrected command into the same
    # folder was then refused as "holds a different run", hiding the real error
    wild = tmp_path / "wild.toml"
    wild.write_text("[camera]\nmount_offset_mm = 5000.0\n")
    out = tmp_path / "run"
    status, _, stderr = gva("reproduce", "real", "--out", out, "--variants", wild, *TINY)
    assert status == 2 and "mount_offset_mm" in stderr, stderr
    assert not out.exists()
