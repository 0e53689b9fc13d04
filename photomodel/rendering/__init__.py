"""The one renderer of Face Studio and what draws or reads with it; one module per job.

| module | does |
|---|---|
| :mod:`~photomodel.rendering.renderer` | the renderer (moderngl on EGL, one per thread): ``render``, |
| | ``rasterize_barycentric``, textures, programs for shader code beside it; ``vertex_normals`` |
| :mod:`~photomodel.rendering.barycentric` | the pass behind ``rasterize_barycentric``, and its result |
| :mod:`~photomodel.rendering.view_dependent_pass` | view-dependent texturing in shaders on the renderer's context |
| :mod:`~photomodel.rendering.sampling` | bilinear look-ups on the CPU: images at pixels, textures at ``uv`` |
| :mod:`~photomodel.rendering.depth` | the depth-map visibility test (§5.2.1): texturing, overlay, synthetic |

Writing images is :mod:`photomodel.exchange.files`' job (``encode_png``, ``atomic_write_bytes``).
"""
