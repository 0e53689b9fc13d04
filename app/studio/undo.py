"""The studio's undo stack, without Qt: :class:`UndoCommand` and :class:`UndoStack`.

:class:`app.studio_state.StudioModel` owns one :class:`UndoStack` (``model.undo_stack``); the
commands of :mod:`app.studio.commands` (one per artist action, each calling the model's edit
primitives) are pushed on it by the widgets, and the *Edit* menu's actions undo and redo it. It
keeps QUndoStack's semantics where the studio used them — ``push`` runs the command, a push after
an undo drops the undone commands, a macro is one step, the clean state marks the saved project —
and announces its changes through :class:`~app.studio.events.Signal` objects, so tests and
scripts drive the same history the menu shows.
"""

from __future__ import annotations

from app.studio.events import Signal

__all__ = ["UndoCommand", "UndoStack"]


class UndoCommand:
    """One undoable action: :meth:`redo` does it (also the first time, on push), :meth:`undo` takes
    it back; :attr:`text` names it for the *Edit* menu (``"Move chin in front"``)."""

    def __init__(self, text: str = ""):
        self.text = text

    def redo(self) -> None:
        raise NotImplementedError

    def undo(self) -> None:
        raise NotImplementedError


class _Macro(UndoCommand):
    """Commands pushed between :meth:`UndoStack.begin_macro` and :meth:`UndoStack.end_macro`: one step."""

    def __init__(self, text: str):
        super().__init__(text)
        self.children: list[UndoCommand] = []

    def redo(self) -> None:
        for c in self.children:
            c.redo()

    def undo(self) -> None:
        for c in reversed(self.children):
            c.undo()


class UndoStack:
    """The edits of one project, undone and redone in order.

    ``commands[:index]`` are done, ``commands[index:]`` undone (what :meth:`redo` does again).

    Events (:class:`~app.studio.events.Signal`)
    -------------------------------------------
    index_changed (index) — a command was pushed, undone or redone, or the history cleared: the
        project may have changed.
    changed () — anything the *Edit* menu shows may have changed: the index, the texts, the clean
        state.
    """

    def __init__(self):
        self.index_changed = Signal()
        self.changed = Signal()
        self._commands: list[UndoCommand] = []
        self._index = 0
        self._clean_index: int | None = 0  # None: the saved state was dropped by a push after an undo
        self._macro: _Macro | None = None

    # ------------------------------------------------------------------ state
    def __len__(self) -> int:
        """The number of commands kept (done and undone; a macro counts once)."""
        return len(self._commands)

    @property
    def index(self) -> int:
        """How many commands are done."""
        return self._index

    @property
    def can_undo(self) -> bool:
        return self._index > 0 and self._macro is None

    @property
    def can_redo(self) -> bool:
        return self._index < len(self._commands) and self._macro is None

    @property
    def undo_text(self) -> str:
        """The text of the command :meth:`undo` would take back ("" when none)."""
        return self._commands[self._index - 1].text if self.can_undo else ""

    @property
    def redo_text(self) -> str:
        """The text of the command :meth:`redo` would do again ("" when none)."""
        return self._commands[self._index].text if self.can_redo else ""

    @property
    def is_clean(self) -> bool:
        """Whether the project is as it was at the last :meth:`set_clean` (its save) or :meth:`clear`."""
        return self._clean_index == self._index

    # ------------------------------------------------------------------ changes
    def push(self, command: UndoCommand) -> None:
        """Do ``command`` (its :meth:`~UndoCommand.redo`) and keep it; the undone commands are dropped.

        Inside a macro the command joins it. When ``redo`` raises, nothing is kept.
        """
        command.redo()
        if self._macro is not None:
            self._macro.children.append(command)
            return
        self._keep(command)

    def begin_macro(self, text: str) -> None:
        """Start one step made of the commands pushed until :meth:`end_macro` (no nesting)."""
        if self._macro is not None:
            raise RuntimeError(f"a macro ({self._macro.text!r}) is already open")
        self._macro = _Macro(text)

    def end_macro(self) -> None:
        """Close the macro: its commands are one step (none pushed: nothing kept)."""
        if self._macro is None:
            raise RuntimeError("no macro is open")
        macro, self._macro = self._macro, None
        if macro.children:
            self._keep(macro)
        else:
            self.changed.emit()

    def undo(self) -> bool:
        """Take back the last done command; False when there is none."""
        if not self.can_undo:
            return False
        self._commands[self._index - 1].undo()
        self._index -= 1
        self._announce()
        return True

    def redo(self) -> bool:
        """Do the last undone command again; False when there is none."""
        if not self.can_redo:
            return False
        self._commands[self._index].redo()
        self._index += 1
        self._announce()
        return True

    def clear(self) -> None:
        """Forget every command (another project): nothing to undo or redo, and clean."""
        self._macro = None
        if not self._commands and self.is_clean:
            return
        self._commands.clear()
        self._index = 0
        self._clean_index = 0
        self._announce()

    def set_clean(self) -> None:
        """Mark the present state as the saved one (:attr:`is_clean` until the next change)."""
        if self._clean_index != self._index:
            self._clean_index = self._index
            self.changed.emit()

    # ------------------------------------------------------------------ internals
    def _keep(self, command: UndoCommand) -> None:
        if self._clean_index is not None and self._clean_index > self._index:
            self._clean_index = None  # the saved state was undone and is dropped now
        del self._commands[self._index :]
        self._commands.append(command)
        self._index += 1
        self._announce()

    def _announce(self) -> None:
        self.index_changed.emit(self._index)
        self.changed.emit()
