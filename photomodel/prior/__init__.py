"""A localised statistical face prior (seed 004, Brunton, Bolkart & Wuhrer) and fitting scans with it.

Built from ICT-FaceKit's identities moved onto the generic mesh by the rig's registration, so it
stands above :mod:`photomodel.rig` and :mod:`photomodel.modeling`; the fit takes it as a wrapper of
its deformation (``fit_expression(..., deform=prior_deformer(mesh, deform_vertices))``), which the
``facestudio fit`` command passes by default (``--no-face-prior`` leaves it out).
"""
