import copy

import numpy as np
import pytest

from robointel.learning.grinding import GrindingSkill, Plate, demonstrate_grinding
from robointel.learning.insertion import HDDScene, InsertionSkill, PegHole
from robointel.program import save_skill


@pytest.fixture(scope="session")
def skill_files(tmp_path_factory, hdd_demos):
    """An insertion and a grinding skill file, each learned from one scripted demonstration (kept small)."""
    d = tmp_path_factory.mktemp("skills")
    scene = HDDScene(PegHole())
    demo = copy.deepcopy(hdd_demos[0])  # demonstrate(PegHole(), default_rng(3), scene=scene), made once
    ins = InsertionSkill(4, centre=scene.tool.tip - scene.tool.radius).fit([demo])
    plate = Plate()
    gdemo = demonstrate_grinding(plate, np.random.default_rng(0), scene=HDDScene(plate, plate.tool()), lines=4,
                                 speed=0.1)
    grind = GrindingSkill(plate, 8).fit([gdemo])
    return {"insert": save_skill(d / "peg.skill.h5", ins), "grind": save_skill(d / "grind.skill.h5", grind),
            "skills": (ins, grind)}
