"""Rigs: ARKit-style blend shapes for any modeled face, from ICT-FaceKit by deformation transfer.

* :mod:`photomodel.rig.ict` — ICT-FaceKit's data as shipped (``ict_facekit.npz``) and ARKit's names.
* :mod:`photomodel.rig.registration` — ICT's head registered onto the generic mesh.
* :mod:`photomodel.rig.transfer` — deformation transfer (Sumner & Popović 2004).
* :mod:`photomodel.rig.build` — one person's rig (:class:`~photomodel.rig.build.RigBuilder`).
* :mod:`photomodel.rig.make_ict_data` — the one-off conversion of ICT's files (kept, not imported).
"""
