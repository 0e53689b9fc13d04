"""Texturing the fitted face from its photographs (Pighin et al. 2002, §5.2): one module per step.

| module | does |
|---|---|
| :mod:`~photomodel.texturing.visibility` | depth-map visibility from each photo's camera (§5.2.1) |
| :mod:`~photomodel.texturing.weights` | weight maps ``g_k = F_k P_k (V_k)`` (§5.2.1, §5.2.3, §5.2.4) |
| :mod:`~photomodel.texturing.cylindrical` | the view-independent cylindrical texture (§5.2.2) |
| :mod:`~photomodel.texturing.view_dependent` | view-dependent rendering from two photographs (§5.2.3) |
| :mod:`~photomodel.texturing.job` | extraction + exports as one job for the CLI and the studio |

The weight maps combine visibility, cubic feathering, positional certainty and (view-dependent
only) view similarity, with the single-view fallback of §5.2.4; the cylindrical texture is
``cylindrical_texture``, view-dependent rendering ``ViewDependentTexture``, and the job
(``texture_expression``, ``encode_texture_outputs``; stored by :mod:`photomodel.project.results`)
is the one path shared by ``facestudio texture`` and the studio. Nothing is imported here, so
importing the package costs nothing: import from the module that does the work. The exported
files (OBJ/PLY/glTF) are :mod:`photomodel.exchange`'s job; the design and measurements are in
``docs/texturing.md``.
"""
