"""Text and picture tasks: phrasings split like scenes, phrase files, and what a model is given."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from harness.inputs.trial_settings import TrialSettings
from perception.interface import ConditionKind
from sim.errors import InvalidInputError
from sim.tasks.phrasings import Phrasings, normalised, read_phrase_file
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE, get_scene_spec
from sim.tasks.task_spec import SIDES, ConditionForm
from sim.tasks.task_toml import load_task, task_from_toml, task_to_toml, with_test_phrases
from sim.world.pictures import PICTURES_PER_SPLIT, render_picture

TEXT_TASK = """
name = "t"
[objects]
choose = "one_of_each"
count = 3
[targets]
select = "condition"
[condition]
kind = "object_type"
given_as = "text"
[condition.phrases.train]
sponge = ["the sponge"]
spray_bottle = ["the spray bottle"]
mug = ["the mug"]
[condition.phrases.test]
sponge = ["the scouring pad"]
spray_bottle = ["the sprayer"]
mug = ["the cup"]
"""
KNOWN = YUMI_SCENE.object_types + SIDES


def test_text_tasks_present_the_scenes_of_their_one_hot_twins():
    for name, twin in (("selected-type-text", "selected-type"),
                       ("selected-position-text", "selected-position")):
        task, one_hot = load_task(name), load_task(twin)
        assert task.given_as is ConditionForm.TEXT and task.model_condition is ConditionKind.TEXT
        for scene_name in ("yumi", "paper-sim"):
            spec = get_scene_spec(scene_name)
            for stream in SeedStream:
                for index in range(10):
                    scene = sample_scene(task, spec, 3, stream, index)
                    other = sample_scene(one_hot, spec, 3, stream, index)
                    assert (scene.objects, scene.targets, scene.condition) == \
                        (other.objects, other.targets, other.condition)
                    assert other.query is None and other.given == other.condition


def test_training_scenes_say_training_phrasings_and_test_scenes_test_ones():
    task = load_task("selected-type-text")
    phrasings = task.phrasings
    assert phrasings is not None
    seen = {"train": set(), "test": set()}
    for split, stream in (("train", SeedStream.TRAIN), ("test", SeedStream.TEST)):
        for index in range(40):
            scene = sample_scene(task, YUMI_SCENE, 0, stream, index)
            for value in scene.askable():
                asked = scene.asking(value, task)
                assert asked.given.kind is ConditionKind.TEXT
                assert asked.given.value in phrasings.of(split, value)
                seen[split].add(asked.given.value)
            record = scene.to_record()
            assert record["query"] == {"kind": "text", "value": scene.given.value}
            assert record["condition"]["value"] == scene.condition.value
    assert not {normalised(p) for p in seen["train"]} & {normalised(p) for p in seen["test"]}
    assert len(seen["test"]) > 6  # several phrasings per target are drawn, not one


def test_a_task_file_with_phrasings_reads_back_and_refuses_shared_or_missing_ones():
    task = task_from_toml(TEXT_TASK)
    assert dataclasses.replace(task_from_toml(task_to_toml(task)), source=task.source) == task
    with pytest.raises(InvalidInputError, match=r"condition.phrases.test.mug = 'The  Mug' .* "
                                                r"not in condition.phrases.train"):
        task_from_toml(TEXT_TASK.replace('mug = ["the cup"]', 'mug = ["The  Mug"]'))
    with pytest.raises(InvalidInputError, match=r"condition.phrases = 'absent' .* exactly when "
                                                r"condition.given_as = 'text'"):
        task_from_toml(TEXT_TASK.split("[condition.phrases.train]")[0])
    with pytest.raises(InvalidInputError, match=r"condition.phrases = \['train'\] .* exactly "
                                                r"the tables train and test"):
        task_from_toml(TEXT_TASK.split("[condition.phrases.test]")[0])
    no_mug = task_from_toml(TEXT_TASK.replace('mug = ["the cup"]\n', ""))
    with pytest.raises(InvalidInputError, match=r"condition.phrases.test = .*no phrasings for "
                                                r"\['mug'\]"):
        sample_scene(no_mug, YUMI_SCENE, 0, SeedStream.TEST, 0)
    with pytest.raises(InvalidInputError, match=r"given_as = 'image' .* \(a picture shows an "
                                                r"object, not a side"):
        task_from_toml(task_to_toml(load_task("selected-position")).replace(
            'given_as = "one_hot"', 'given_as = "image"'))
    with pytest.raises(InvalidInputError, match=r"condition.given_as = 'speech' is not allowed"):
        task_from_toml(TEXT_TASK.replace('given_as = "text"', 'given_as = "speech"'))


def test_a_phrase_file_replaces_the_test_phrasings(tmp_path):
    task = load_task("selected-type-text")
    path = tmp_path / "mine.tsv"
    path.write_text("# my words\nfetch the absorbent square\tsponge\nthe atomiser\tspray_bottle\n"
                    "\nthe teacup\tmug\nthe port side\tleft\n")
    changed = with_test_phrases(task, path, YUMI_SCENE.object_types, KNOWN)
    assert changed.phrasings.of("test", "sponge") == ("fetch the absorbent square",)
    assert changed.phrasings.of("test", "left") == ()  # another task's target: left out
    assert changed.phrasings.train == task.phrasings.train
    scene = sample_scene(changed, YUMI_SCENE, 0, SeedStream.TEST, 0)
    assert scene.given.value in ("fetch the absorbent square", "the atomiser", "the teacup")
    settings = TrialSettings(model="oracle", task="selected-type-text", phrases=str(path))
    assert settings.identity()["task"]["phrasings"]["test"]["mug"] == ["the teacup"]
    assert settings.identity() != TrialSettings(model="oracle", task="selected-type-text"
                                                ).identity()  # a resumed run keeps its words
    assert settings.inputs()["phrases_file"] == path


@pytest.mark.parametrize(("text", "message"), [
    ("the teacup mug\n", r"line 1 = 'the teacup mug' .* phrase<TAB>target"),
    ("the teacup\tpurple\n", r"line 1 = 'purple' .* one of sponge, spray_bottle, mug"),
    ("the teacup\tmug\n", r"no line for \['sponge', 'spray_bottle'\]"),
    ("# nothing\n", "at least one phrase<TAB>target line"),
])
def test_a_bad_phrase_file_is_refused_naming_the_line(tmp_path, text, message):
    path = tmp_path / "bad.tsv"
    path.write_text(text)
    with pytest.raises(InvalidInputError, match=message):
        with_test_phrases(load_task("selected-type-text"), path, YUMI_SCENE.object_types, KNOWN)


def test_phrases_need_a_text_task(tmp_path):
    path = tmp_path / "p.tsv"
    path.write_text("the teacup\tmug\n")
    with pytest.raises(InvalidInputError, match="a task given as text"):
        TrialSettings(model="oracle", task="selected-type", phrases=str(path))


def test_picture_tasks_show_a_picture_of_the_named_type_from_their_split():
    task = load_task("selected-type-image")
    assert task.model_condition is ConditionKind.IMAGE
    for stream, split in ((SeedStream.TRAIN, "train"), (SeedStream.TEST, "test")):
        scene = sample_scene(task, YUMI_SCENE, 0, stream, 1)
        pictures = [render_picture("yumi", scene.condition.value, split, n).tobytes()
                    for n in range(PICTURES_PER_SPLIT)]
        assert scene.given.kind is ConditionKind.IMAGE
        assert scene.given.picture.tobytes() in pictures
        assert scene.to_record()["query"] == {"kind": "image", "value": scene.given.value}


def test_training_and_test_pictures_never_meet_and_differ_by_view():
    for scene, object_type in (("yumi", "mug"), ("paper-sim", "duck")):
        train = {render_picture(scene, object_type, "train", n).tobytes() for n in range(12)}
        test = {render_picture(scene, object_type, "test", n).tobytes() for n in range(12)}
        assert len(train) == len(test) == 12 and not train & test
    picture = render_picture("yumi", "mug", "test", 0)
    assert picture.shape == (32, 32, 3) and picture.dtype == np.uint8
    assert np.array_equal(picture, render_picture("yumi", "mug", "test", 0))  # deterministic
    with pytest.raises(InvalidInputError, match="split = 'val'"):
        render_picture("yumi", "mug", "val", 0)
    with pytest.raises(InvalidInputError, match=rf"number = {PICTURES_PER_SPLIT}"):
        render_picture("yumi", "mug", "train", PICTURES_PER_SPLIT)


def test_phrasings_refuse_bad_lists():
    with pytest.raises(InvalidInputError, match=r"train.mug = \[\] .* a list of 1-100"):
        Phrasings((("mug", []),), ())
    with pytest.raises(InvalidInputError, match="distinct phrasings"):
        Phrasings((("mug", ["the mug", "The mug"]),), ())
    with pytest.raises(InvalidInputError, match="printable"):
        Phrasings((("mug", ["the\nmug"]),), ())


STOPWORDS = frozenset("a an the of on to for with at from by in is it me my i you your that "
                      "this and or over up whatever".split())


def _content_words(phrases) -> set[str]:
    return {word.strip("'.,").lower() for phrase in phrases for word in phrase.split()} - \
        STOPWORDS


def test_the_new_wordings_example_shares_no_content_word_with_training(tmp_path):
    """examples/phrases/new-wordings.tsv: 3 phrases per target, words training never used."""
    path = Path(__file__).parents[3] / "examples" / "phrases" / "new-wordings.tsv"
    table = read_phrase_file(path, KNOWN)
    assert {target: len(phrases) for target, phrases in table} == dict.fromkeys(KNOWN, 3)
    trained = set()
    for name in ("selected-type-text", "selected-position-text"):
        trained |= _content_words(p for _, phrases in load_task(name).phrasings.train
                                  for p in phrases)
    new = _content_words(p for _, phrases in table for p in phrases)
    # No word in common, nor one inside the other ("teacup" holds "cup").
    shared = {(n, t) for n in new for t in trained if n in t or t in n}
    assert not shared, shared


def test_the_retired_test_phrasings_still_serve_as_a_phrase_file():
    """examples/phrases/retired-test-phrasings.tsv: no phrasing trained on, every target."""
    path = Path(__file__).parents[3] / "examples" / "phrases" / "retired-test-phrasings.tsv"
    table = dict(read_phrase_file(path, KNOWN))
    assert set(table) == set(KNOWN) and all(len(phrases) >= 8 for phrases in table.values())
    for name in ("selected-type-text", "selected-position-text"):
        task = load_task(name)
        trained = {p.lower() for _, phrases in task.phrasings.train for p in phrases}
        tested = {p.lower() for _, phrases in task.phrasings.test for p in phrases}
        retired = {p.lower() for phrases in table.values() for p in phrases}
        assert not retired & trained and not retired & tested
