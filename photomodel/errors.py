"""Exceptions raised at the boundaries of the modeling core; messages name the culprit."""


class FaceStudioError(Exception):
    """Base class of every error Face Studio reports to a user."""


class ProjectError(FaceStudioError):
    """A project file is missing, malformed or refers to something that is not there."""


class FitError(FaceStudioError):
    """The clicks cannot support a fit (too few, one view only, degenerate, NaN, ...)."""


class SampleDataError(FaceStudioError):
    """The sample data (menpo3d source distribution) cannot be obtained or is corrupt."""
