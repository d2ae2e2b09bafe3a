"""Scenes labelled by the catalog: placed, settled and seen as a trial's, never picked.

A demonstration (:mod:`harness.inputs.collector`) costs a pick in physics per target, 1-6 s a
scene, and is kept only where every pick succeeded. Perception needs less: the image and each
target's grasp. Here a scene is set up exactly as a trial's (:meth:`TrialRunner.setup
<sim.trials.trial_runner.TrialRunner.setup>`: the objects dropped as the task places them,
settled 0.25 s, the look applied), seen through the task's sensor with the noise of the
demonstration's first image, and each target labelled with the grasp the oracle would use where
it rests (:meth:`~sim.trials.trial_runner.TrialRunner.truth`: the catalog's grasp at the settled
pose, read by the same observer a demonstration's labels come from). A few hundred scenes a
minute; none verified by a pick.

A task with several targets: a demonstration takes an image before each pick, the targets picked
so far set aside and the arm back at its start. Here each later image is the same scene with
the earlier targets taken off the table and nothing else moved (a pick that brushed nothing),
so a ``multiple`` scene gives three samples, as a demonstration does, labelled and marked
``"taken"`` alike: the model learns the second and third picks' tables too, at the cost of a
render each.
"""

from __future__ import annotations

from collections.abc import Callable

from tqdm import tqdm

from perception.learning.data import JOINT_NAMES_KEY
from perception.learning.mirror import MIRROR_FLAG
from robots.description import RobotDescription
from sim.tasks.mirror_symmetry import mirror_symmetric
from sim.tasks.scene_sampling import Scene
from sim.tasks.scene_specs import SceneSpec
from sim.tasks.task_spec import TaskSpec
from sim.trials.pick_images import PickImages
from sim.trials.scene_sets.samples import Collected, Sample, scene_samples
from sim.trials.trial_runner import TrialRunner


def collect_catalog_scenes(task: TaskSpec, spec: SceneSpec, scene_at: Callable[[int], Scene],
                           size: int, every_condition: bool, robot: RobotDescription,
                           bar: tqdm) -> Collected:
    """Scenes ``scene_at(0)`` ... ``scene_at(size - 1)``, each seen and labelled, never picked.

    The camera record is the mounted camera's; ``extra`` names the robot's joints and whether
    the task is mirror-symmetric, as a demonstration's does.
    """
    samples: list[Sample] = []
    with TrialRunner(task, robot=robot) as runner:
        images = PickImages(runner, hidden_share_max=1.0)  # the arm never moves: no approach
        for index in range(size):
            scene = scene_at(index)
            bodies = runner.setup(scene)
            targets = [bodies[t] for t in scene.targets]
            images.start(targets)
            for number, body in enumerate(targets):
                if number:  # the earlier target taken off the table, as a pick sets it aside
                    runner.world.remove_object(targets[number - 1])
                images.saw(runner.sight(body).frame, None)
            samples += scene_samples(task, scene, bodies, images, every_condition)
            bar.update()
        camera = runner.mounted_camera.record()
        extra = {JOINT_NAMES_KEY: list(images.joint_names),
                 MIRROR_FLAG: mirror_symmetric(task, spec, runner.mounted_camera.config)}
    return Collected(samples, camera, extra)
