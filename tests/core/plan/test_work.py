"""`planning.Work` declares every field the Blender side sets on it (pure, no Blender)."""

import dataclasses

import pytest

from core.plan.planning import Work


def test_work_declares_the_layer_fields_and_takes_no_other():
    work = Work(read=None, result=None, selection=None, plan=None)
    names = [f.name for f in dataclasses.fields(Work)]
    assert names[5:] == [
        "receivers",
        "layer_bake",
        "layer_sources",
        "layer_figures",
        "layer_floors",
        "water",  # blender/commands/water_stage.py's WaterStage (issue 26)
    ]
    assert all(getattr(work, n) is None for n in names[5:]) and work.timings == {}
    work.layer_figures = "figures"  # declared: set by blender/commands/layer_stage.py
    with pytest.raises(AttributeError):
        work.layer_extra = 1  # not declared: slots refuse it
