"""The studio's work, apart from its state and any widget: what :class:`app.studio_state.StudioModel` calls.

Each collaborator does one kind of work on the project the model holds and returns what it made;
the model stores it and announces the change. None imports Qt, so tests and scripts drive them
without a window: :mod:`~app.studio.fitting` (fits, their overlays and click residuals),
:mod:`~app.studio.texturing` (textures of a fit), :mod:`~app.studio.rig` (the rig shown and posed),
:mod:`~app.studio.tracking` (tracking a video with the saved project) and
:mod:`~app.studio.project_file` (the project file's life: new, open, save, autosave, recovery).
:mod:`~app.studio.events` (the model's :class:`~app.studio.events.Signal`) and
:mod:`~app.studio.edits` (the model's edit primitives) are parts of the model itself.
"""
