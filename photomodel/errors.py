"""Exceptions raised at the boundaries of the modeling core; messages name the culprit."""


class FaceStudioError(Exception):
    """Base class of every error Face Studio reports to a user."""


class Cancelled(Exception):
    """Raised inside a long job (a fit, a texture, a photo intake, a tracked clip) when the caller's
    ``cancel()`` returns True; not a :class:`FaceStudioError`: nothing went wrong."""


class ProjectError(FaceStudioError):
    """A project file is missing, malformed or refers to something that is not there."""


class FitError(FaceStudioError):
    """The clicks cannot support a fit (too few, one view only, degenerate, NaN, ...)."""


class SampleDataError(FaceStudioError):
    """The sample data (menpo3d source distribution) cannot be obtained or is corrupt."""


class MissingClicks(FitError):
    """The clicks of an expression cannot support a fit; ``checklist`` lists *everything* missing.

    Attributes
    ----------
    expression : str
    checklist : list[dict], one per missing thing, as
        :meth:`photomodel.modeling.checklist.ChecklistItem.to_dict`: ``feature`` (or None),
        ``photo`` (or None), ``photos_clicked``, ``needed``, ``hint``, ``clicked_in``, ``hidden_in``.
    """

    def __init__(
        self,
        expression: str,
        checklist: list[dict],
        *,
        placed: int,
        pose_features: int,
        note: str | None = None,
        needed_photos: int = 2,
    ):
        self.expression = expression
        self.checklist = list(checklist)
        where = "in 2+ photos" if needed_photos >= 2 else "in the photo"
        head = (
            f"expression {expression!r} cannot be fitted yet: {placed} of {pose_features} pose feature(s) "
            f"are clicked {where}; {len(self.checklist)} thing(s) to click:"
        )
        lines = [head] if note is None else [head, f"  ({note})"]
        for it in self.checklist:
            if it.get("feature") is not None:
                lines.append(
                    f"  - {it['feature']}: clicked in {it['photos_clicked']} photo(s), "
                    f"needs {it['needed']} — {it['hint']}"
                )
            else:
                shared = "shared " if needed_photos >= 2 else ""
                lines.append(
                    f"  - photo {it['photo']!r}: {it['photos_clicked']} {shared}click(s), "
                    f"needs {it['needed']} — {it['hint']}"
                )
        super().__init__("\n".join(lines))


class PhotoError(ProjectError):
    """A photograph is missing, truncated, undecodable or unusable; the message names the file.

    A :class:`ProjectError` because a photo is part of a project: whoever reports project
    problems reports these too."""


class NoFaceFound(FaceStudioError):
    """The automatic landmark detector finds no face in a photo; its landmarks are clicked by hand."""
