"""The studio model's undo stack (app.studio.undo) on real edits, without any window."""

from __future__ import annotations

import numpy as np
import pytest

from app.studio.commands import AddExpressionCommand, ScanFitCommand, SetHiddenCommand, SetPointCommand
from app.studio.undo import UndoCommand, UndoStack
from app.studio_state import StudioModel


@pytest.fixture
def model(project_copy):
    m = StudioModel()
    m.open(project_copy)
    return m


def test_a_moved_click_is_undone_and_redone(model):
    stack, events = model.undo_stack, []
    stack.index_changed.connect(lambda i: events.append(i))
    assert len(stack) == 0 and stack.is_clean and not stack.can_undo and not stack.can_redo
    old = model.photo("front").points["chin"].copy()
    stack.push(SetPointCommand(model, "neutral", "front", "chin", old + 5.0))
    np.testing.assert_array_equal(model.photo("front").points["chin"], old + 5.0)  # push does it
    assert stack.can_undo and stack.undo_text == "Move chin in front" and not stack.is_clean
    assert model.modified

    assert stack.undo()
    np.testing.assert_array_equal(model.photo("front").points["chin"], old)
    assert stack.can_redo and stack.redo_text == "Move chin in front" and stack.is_clean
    assert stack.redo()
    np.testing.assert_array_equal(model.photo("front").points["chin"], old + 5.0)
    assert not stack.redo() and events == [1, 0, 1]


def test_a_push_after_an_undo_drops_the_undone_edit(model):
    stack = model.undo_stack
    old = model.photo("front").points["chin"].copy()
    stack.push(SetPointCommand(model, "neutral", "front", "chin", old + 5.0))
    stack.undo()
    stack.push(SetHiddenCommand(model, "neutral", "front", "chin", True))
    assert len(stack) == 1 and not stack.can_redo and stack.undo_text == "Hide chin in front"
    np.testing.assert_array_equal(model.photo("front").points["chin"], old)  # the move is gone for good


def test_save_marks_the_stack_clean_and_opening_clears_it(model, project_copy):
    stack = model.undo_stack
    old = model.photo("front").points["chin"].copy()
    stack.push(SetPointCommand(model, "neutral", "front", "chin", old + 5.0))
    stack.push(SetPointCommand(model, "neutral", "front", "chin", old + 7.0))
    assert not stack.is_clean
    model.save()
    assert stack.is_clean and not model.modified and stack.index == 2
    stack.undo()
    assert not stack.is_clean
    stack.redo()
    assert stack.is_clean
    stack.undo()
    stack.push(SetHiddenCommand(model, "neutral", "front", "chin", True))  # the saved state is gone
    assert not stack.is_clean
    while stack.undo():  # not even with every edit undone: the file holds the moved chin
        assert not stack.is_clean

    model.open(project_copy)  # another project: no history of the previous one
    assert len(stack) == 0 and stack.is_clean and not stack.can_undo


def test_a_macro_is_one_step(model):
    stack, changes = model.undo_stack, []
    stack.index_changed.connect(changes.append)
    before = model.expression_name
    old = model.photo("front").points["chin"].copy()
    stack.begin_macro("Add an expression and move the chin")
    stack.push(SetPointCommand(model, "neutral", "front", "chin", old + 5.0))
    stack.push(AddExpressionCommand(model, "smile2"))
    assert changes == [] and not stack.can_undo  # inside the macro: no step yet
    stack.end_macro()
    assert len(stack) == 1 and changes == [1] and model.expression_name == "smile2"
    assert stack.undo_text == "Add an expression and move the chin"
    stack.undo()
    assert model.expression_name == before and "smile2" not in [e.name for e in model.project.expressions]
    np.testing.assert_array_equal(model.photo("front", before).points["chin"], old)
    stack.redo()
    assert model.expression_name == "smile2"
    np.testing.assert_array_equal(model.photo("front", "neutral").points["chin"], old + 5.0)


def test_a_command_that_fails_is_not_kept():
    class Fails(UndoCommand):
        def redo(self):
            raise ValueError("no")

    stack = UndoStack()
    with pytest.raises(ValueError):
        stack.push(Fails("fails"))
    assert len(stack) == 0 and not stack.can_undo and stack.is_clean


def test_a_scans_fit_is_undone_to_no_fit_and_redone(model):
    """ScanFitCommand (*Fit → Add scan…*) on a project without a fit: undo leaves none, redo the scan's
    again; the clicks are never touched (the fit itself is tests/test_gui_fit_scan.py's)."""
    from photomodel.prior.scan_expression import ScanExpressionFit
    from photomodel.project.datamodel import ExpressionResult

    V = model.mesh.vertices + 1.0
    made = ScanExpressionFit(
        "neutral", V, ExpressionResult(report={"scan_fit": {"unit": "m"}}), {"scan": "head.ply", "unit": "m"}
    )
    clicks = {p.id: dict(p.points) for p in model.photos}
    model.undo_stack.push(ScanFitCommand(model, made))
    assert model.fit("neutral").from_scan and model.project.expression("neutral").result is made.result
    assert model.undo_stack.undo_text == "Fit neutral to head.ply" and model.modified
    model.undo_stack.undo()
    assert model.fit("neutral") is None and model.project.expression("neutral").result is None
    model.undo_stack.redo()
    np.testing.assert_array_equal(model.fit("neutral").vertices, V)
    assert {p.id: dict(p.points) for p in model.photos} == clicks
