"""Recordings of pick trials: what the model saw beside what the robot did, as a GIF.

A :class:`TrialRecorder` is a :class:`~sim.trials.runner_hooks.TrialObserver`: the runner hands it
each image a prediction was made from, with the prediction, and calls it after every physics
step.
Every ``frame_every_s`` of simulated time it renders a second, wider camera that looks at the
robot and the table (:data:`ROBOT_VIEW`), and keeps a frame: the head camera's last image with
the predicted grasps (white) and attention points (numbered by head, :mod:`perception.drawing`)
drawn on the left, the robot's
view on the right, a caption strip on top::

    recorder = TrialRecorder()
    with TrialRunner(task, model, observer=recorder, robot=robot) as runner:
        recorder.start("kqv / single, trial 0")
        record = runner.run(scene, 0, seed, "kqv")
        frames = recorder.finish(record.outcome.value)
    write_gif("trial.gif", *join_trials([frames]))

Rendering only reads the world, so a recorded trial ends as it would have unrecorded.
Frames start with the first prediction (the objects have settled by then).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from perception.camera import RgbdFrame
from perception.drawing import (
    CAPTION_LINE_PX,
    draw_dot,
    draw_number,
    enlarge,
    head_colour,
    with_caption,
)
from perception.files import atomic_write
from perception.interface import Prediction
from robots.description import CameraMount
from sim.errors import InvalidInputError
from sim.world.head_camera import CameraConfig, HeadCamera
from sim.world.lighting import Lighting
from sim.world.yumi_world import World

GRASP_DOT_PX = 2.0
"""Radius of a predicted grasp's dot on the head camera's panel [px]."""
ROBOT_VIEW = CameraConfig.for_mount(CameraMount((1.1, -0.5, 0.6), (0.28, 0.0, 0.2)),
                                   vertical_fov_deg=52.0, horizontal_fov_deg=None)
"""A camera in front of the robot, to its right, that sees both arms and the workspace."""
CAPTION_PX = CAPTION_LINE_PX
"""Height of the caption strip above the two panels."""
MAX_FRAMES = 40
"""Frames kept per trial: longer trials keep evenly spaced ones (and always the last)."""


@dataclasses.dataclass(frozen=True)
class RecordingSettings:
    """How a trial is recorded.

    Args:
        frame_every_s: Simulated time between two frames [s].
        max_frames: Frames kept per trial (evenly spaced, the last one always kept).
        robot_view: The camera that watches the robot.

    """

    frame_every_s: float = 0.15
    max_frames: int = MAX_FRAMES
    robot_view: CameraConfig = ROBOT_VIEW

    def __post_init__(self) -> None:
        if not self.frame_every_s > 0.0:
            raise InvalidInputError("frame_every_s", self.frame_every_s, "a time > 0 s")
        if self.max_frames < 2:
            raise InvalidInputError("max_frames", self.max_frames, "an integer >= 2")


class TrialRecorder:
    """Keeps the frames of one trial at a time; see the module docstring.

    Args:
        settings: Frame rate, frame count and the robot view.
        lighting: The light the robot view is rendered with (the task's, so a dark trial
            looks dark); None: the camera's default.

    """

    def __init__(self, settings: RecordingSettings | None = None,
                 lighting: Lighting | None = None) -> None:
        self.settings = settings or RecordingSettings()
        self.lighting = lighting
        self.camera = HeadCamera(self.settings.robot_view)
        self.caption = ""
        self.frames: list[np.ndarray] = []
        self.inset: np.ndarray | None = None  # an image condition's picture, drawn in it
        self._seen: np.ndarray | None = None  # the head panel: last image with its points
        self._world: World | None = None  # the world of the last physics step
        self._next_frame_s = 0.0

    def start(self, caption: str, inset: np.ndarray | None = None) -> None:
        """Starts a new trial's recording, captioned ``caption``.

        ``inset``: a picture drawn in the head panel's top right corner (an image condition's).
        """
        self.caption, self.frames, self._seen, self._world = caption, [], None, None
        self.inset = inset
        self._next_frame_s = 0.0

    def saw(self, frame: RgbdFrame, prediction: Prediction | None) -> None:
        """Takes the image a prediction was made from; draws its grasps and attention points.

        Each predicted grasp position is a white dot (where the camera's calibration projects
        it), each attention point a coloured, numbered one; a closed loop's re-predictions each
        replace the panel, so the grasp is seen following a moved target.

        A prediction the robot could not act on (None) leaves the image without points, so a
        trial that failed in perception still shows what the model saw.
        """
        panel = np.array(frame.rgb, dtype=np.uint8, copy=True)
        for target in () if prediction is None else prediction.targets:  # the grasps, in white
            uv = frame.camera.project(np.asarray(target.position_m, dtype=float)[None])[0]
            draw_dot(panel, tuple(uv), GRASP_DOT_PX, (255, 255, 255), outline_px=1.0)
        points = np.zeros((0, 2)) if prediction is None else np.asarray(
            prediction.attention_px, dtype=float).reshape(-1, 2)  # (p, 2)
        for head, point in enumerate(points):
            # Smaller than perception.drawing's dots at scale 1: legible on a 128 px panel.
            draw_dot(panel, tuple(point), 2.5, head_colour(head), outline_px=1.0)
            if np.all(np.isfinite(point)):
                draw_number(panel, head, (round(point[0]) + 5, round(point[1]) - 2),
                            head_colour(head))
        if self.inset is not None:  # framed in white, in the corner no workspace pixel uses
            h, w = self.inset.shape[:2]
            panel[:h + 2, -w - 2:] = 255
            panel[1:h + 1, -w - 1:-1] = self.inset
        self._seen = panel

    def stepped(self, world: World) -> None:
        """After a physics step: a frame every ``frame_every_s``, from the first prediction on."""
        self._world = world
        if self._seen is None or world.time_s + 1e-9 < self._next_frame_s:
            return
        self._next_frame_s = world.time_s + self.settings.frame_every_s
        self.frames.append(self._frame(world, self._seen))

    def finish(self, ending: str) -> list[np.ndarray]:
        """The trial's frames (at most ``max_frames``), the last captioned with ``ending``.

        A trial that ended before the robot moved (a refused plan) still gets one frame.
        """
        if not self.frames and self._seen is not None and self._world is not None:
            self.frames.append(self._frame(self._world, self._seen))
        frames = self.frames
        if len(frames) > self.settings.max_frames:
            kept = np.linspace(0, len(frames) - 1, self.settings.max_frames).round().astype(int)
            frames = [frames[i] for i in kept]
        if frames:
            last = frames[-1].copy()
            _caption(last, f"{self.caption}: {ending}")
            frames = [*frames[:-1], last]
        self.frames, self._seen = [], None
        return frames

    def _frame(self, world: World, seen: np.ndarray) -> np.ndarray:
        """One frame: ``seen`` (the head panel) beside the robot's view now, captioned."""
        view = self.camera.render(world.client, self.lighting)
        head = _fit(seen, view.shape[0])
        frame = np.zeros((CAPTION_PX + view.shape[0], head.shape[1] + view.shape[1], 3),
                         dtype=np.uint8)
        frame[CAPTION_PX:, :head.shape[1]] = head
        frame[CAPTION_PX:, head.shape[1]:] = view
        _caption(frame, self.caption)
        return frame


def _fit(image: np.ndarray, height_px: int) -> np.ndarray:
    """``image`` resized to ``height_px`` rows (nearest neighbour), keeping its aspect."""
    if image.shape[0] == height_px:
        return image
    return enlarge(image, height_px, round(image.shape[1] * height_px / image.shape[0]))


def _caption(frame: np.ndarray, text: str) -> None:
    """Writes ``text`` in the frame's caption strip (:func:`perception.drawing.with_caption`)."""
    frame[:CAPTION_PX] = with_caption(frame[CAPTION_PX:CAPTION_PX], [text])


def join_trials(trials: Sequence[Sequence[np.ndarray]], frame_ms: int = 150,
                last_ms: int = 1500) -> tuple[list[np.ndarray], list[int]]:
    """The frames of several trials one after another, and how long each shows [ms].

    A trial's last frame (its outcome in the caption) stays ``last_ms``, the others
    ``frame_ms``.
    """
    frames: list[np.ndarray] = []
    durations: list[int] = []
    for trial in trials:
        frames += list(trial)
        durations += [frame_ms] * (len(trial) - 1) + [last_ms] * bool(trial)
    return frames, durations


def write_gif(path: str | Path, frames: Sequence[np.ndarray], durations_ms: Sequence[int],
              colours: int = 128) -> Path:
    """Writes uint8 (H, W, 3) ``frames`` as a looping GIF, frame ``k`` shown ``durations_ms[k]``.

    Each frame is reduced to its own palette of ``colours`` (Pillow's median cut); the file is
    written atomically.
    """
    from PIL import Image

    if not frames:
        raise InvalidInputError("frames", 0, "at least one frame")
    if len(durations_ms) != len(frames):
        raise InvalidInputError("durations_ms", len(durations_ms),
                                f"one duration per frame ({len(frames)})")
    images = [Image.fromarray(np.asarray(f, dtype=np.uint8)).quantize(colours) for f in frames]
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(out, lambda temporary: images[0].save(
        temporary, format="GIF", save_all=True, append_images=images[1:],
        duration=list(durations_ms), loop=0, optimize=True))
    return out
