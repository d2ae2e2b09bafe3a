import numpy as np
import pytest
from user_models import CentreModel, DepthReader, MyKqv, synthetic_dataset

from perception.interface import InvalidInputError
from perception.learning.checkpoint import CheckpointError
from perception.learning.evaluate import predict_dataset
from perception.learning.train import TrainConfig
from perception.models.kqv import KqvModel
from perception.registry import MODELS, load_model, model_class


def test_registered_name():
    assert model_class("kqv") is KqvModel
    assert MODELS["kqv"] is KqvModel


def test_unknown_name_lists_the_registered_ones():
    with pytest.raises(InvalidInputError, match=r"model = 'kvq' is not allowed: a registered "
                                                r"name \(kqv, keypoint, dsae, conv-ae, fcn, "
                                                r"keypoint-16, keypoint-min, dsae-16, kqv-mlp, "
                                                r"kqv-paper, keypoint-16-helped, "
                                                r"keypoint-min-helped, fcn-helped\), a name "
                                                r"an installed package registers in "
                                                r"'gva.models' \(none installed\), or "
                                                r"'package.module:Class'"):
        model_class("kvq")


def test_a_users_model_by_module_and_class():
    assert model_class("user_models:CentreModel") is CentreModel
    model = model_class("user_models:CentreModel")()
    assert model.predict(np.zeros((8, 8, 3), np.uint8)).targets[0].position_m[0] == 0.4


def test_bad_module():
    with pytest.raises(InvalidInputError, match=r"an importable module; importing module "
                                                r"'no_such_module' raised ModuleNotFoundError: "
                                                r".* \(is its folder on PYTHONPATH"):
        model_class("no_such_module:Model")


def test_missing_class():
    with pytest.raises(InvalidInputError, match=r"a class that module 'user_models' defines; "
                                                r"it has no 'Missing'"):
        model_class("user_models:Missing")


def test_class_that_is_not_a_model():
    with pytest.raises(InvalidInputError, match=r"a subclass of perception.interface."
                                                r"PerceptionModel; NotAModel is"):
        model_class("user_models:NotAModel")


def test_malformed_path():
    with pytest.raises(InvalidInputError, match=r"'package.module:Class' with both parts"):
        model_class("user_models:")


@pytest.fixture(scope="module")
def tiny_checkpoints(tmp_path_factory):
    dataset = synthetic_dataset(size=2)
    folders = {}
    for cls in (KqvModel, MyKqv):
        model = cls.for_dataset(dataset)
        model.fit(dataset, TrainConfig(steps=1, threads=1), progress=False)
        folders[cls.name] = model.save(tmp_path_factory.mktemp(cls.name) / "ckpt")
    return folders


def test_load_model_reads_the_name_from_config(tiny_checkpoints):
    model = load_model(tiny_checkpoints["kqv"])
    assert type(model) is KqvModel


def test_load_model_of_an_unregistered_model_needs_its_class(tiny_checkpoints):
    folder = tiny_checkpoints["my-kqv"]
    with pytest.raises(CheckpointError, match=r"names model 'my-kqv', which is not registered "
                                              r"\(kqv, keypoint, .*, fcn-helped\); pass "
                                              r"model='package.module:Class'"):
        load_model(folder)
    assert type(load_model(folder, "user_models:MyKqv")) is MyKqv
    with pytest.raises(CheckpointError, match=r"a checkpoint of model 'my-kqv', not 'kqv'"):
        load_model(folder, "kqv")
    with pytest.raises(InvalidInputError, match=r"a LearnableModel"):
        load_model(folder, "user_models:CentreModel")


def test_offline_evaluation_refuses_a_model_that_reads_depth():
    with pytest.raises(InvalidInputError, match=r"model depth-reader: inputs = \['camera', "
                       r"'depth', 'rgb'\] is not allowed: what this run gives \(rgb\); it has "
                       r"no camera, depth"):
        predict_dataset(DepthReader(), synthetic_dataset())
