"""A robot is data (issue 39): no module outside ``robots/`` names a YuMi joint, link or frame.

Code reads them from a :class:`~robots.description.RobotDescription` (``robots.yumi.YUMI`` or
``robots.get_robot``); a literal name would tie it to one robot. Tests may name them: they check
the YuMi's own facts.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CHECKED = ("control", "perception", "sim", "experiments", "benchmarks", "studies", "examples")
YUMI_NAME = re.compile(r"yumi_(joint|link|body)|gripper_[rl]_(joint|base|tcp|finger)")


def test_no_module_outside_robots_names_a_yumi_joint_or_link():
    found = [f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
             for folder in CHECKED for path in sorted((ROOT / folder).rglob("*.py"))
             for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if YUMI_NAME.search(line)]
    assert not found, "\n".join(found)


def test_the_check_sees_a_name():
    assert YUMI_NAME.search('link = "yumi_body"') and YUMI_NAME.search("gripper_r_tcp")
    assert not YUMI_NAME.search("the yumi scene") and not YUMI_NAME.search("gripper.fingers")
