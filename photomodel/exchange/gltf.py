"""Binary glTF 2.0 (``.glb``): the textured face for Blender, game engines and web viewers.

One file holds the JSON scene description and one binary buffer with the vertex data, the
triangle indices and the PNG texture. The scene is a single node with a single mesh of one
triangle primitive (``POSITION``, ``NORMAL``, ``TEXCOORD_0``, 32-bit indices) and one material.

Conventions converted on the way out
------------------------------------
* **Units: millimetres → metres.** glTF's unit is the metre; Face Studio's world is in mm
  (:mod:`photomodel.camera`), so positions are multiplied by :data:`METRES_PER_MM` (0.001) —
  a 150 mm face is 0.15 in the file, the size Blender and AR viewers show.
* **Axes: none.** glTF is right-handed with ``+Y`` up, and the front of an asset faces ``+Z``
  with ``+X`` on its left; our head frame (``+x`` subject's left, ``+y`` up, ``+z`` out of the
  face) is the same frame, so coordinates are not rotated.
* **Texture ``v``: flipped.** glTF's texture origin is the *top*-left of the image (``t``
  down); ours has ``v`` up (:mod:`photomodel.exchange.uv`), so ``TEXCOORD_0 = (u, 1 − v)``. The
  PNG itself is stored as is (row 0 = top in both).
* **Seams.** glTF has one index per vertex, so a vertex whose corners use different ``uv``
  (the seam of a cylindrical texture) is duplicated (:func:`~photomodel.exchange.uv.split_uv_seams`);
  vertices ``0 … n−1`` of the file are the mesh's vertices in order and the copies follow.
  Normals are computed on the unsplit mesh, so the copies shade exactly like their originals.
  The sampler is bilinear, mip-mapped and clamps to the edge, as :mod:`photomodel.rendering.renderer`
  samples, so viewers show what Face Studio renders.

The material is metallic-roughness PBR with the texture as base colour, metallic 0 and
roughness 1 (skin is a dielectric; glTF's default metallic 1 would render the face as dark
metal), double-sided because the face is an open surface that viewers show from behind too.
It also declares ``KHR_materials_unlit`` (optional: viewers without it use the PBR fallback):
the photographs' lighting is already in the texture, as in the paper's renderings (§5.2).

Why pygltflib: glTF is a detailed spec (accessor types, bufferView alignment, GLB chunk
layout); ``pygltflib`` is a small, kept library that models every glTF object as a dataclass
and writes correct GLB containers, so this module states *what* is in the file and the library
handles *how* it is laid out. trimesh can also write glTF but gives no control over the
material, the sampler or (later) morph-target names.

Structure: :class:`GlbDocument` owns the glTF objects and the binary buffer and turns numpy
arrays into accessors (:meth:`GlbDocument.add_accessor`) and PNGs into textures
(:meth:`GlbDocument.add_png_texture`); :func:`encode_glb` composes the face from them. Blend
shapes become further accessors referenced by ``Primitive.targets`` (and ``Mesh.weights``),
an animation accessors referenced by an ``Animation`` — both made with the same two calls.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pygltflib as gl

from photomodel.exchange.files import atomic_write_bytes, encode_png
from photomodel.exchange.uv import check_mesh, check_texture, check_uv, split_uv_seams
from photomodel.rendering.renderer import vertex_normals

#: glTF positions are in metres; Face Studio's in millimetres.
METRES_PER_MM = 0.001

#: The unlit-material extension (viewers that lack it fall back to the PBR material).
UNLIT = "KHR_materials_unlit"

_COMPONENT_TYPES = {
    np.dtype(np.float32): gl.FLOAT,
    np.dtype(np.uint32): gl.UNSIGNED_INT,
    np.dtype(np.uint16): gl.UNSIGNED_SHORT,
    np.dtype(np.uint8): gl.UNSIGNED_BYTE,
}
_TYPES = {1: gl.SCALAR, 2: gl.VEC2, 3: gl.VEC3, 4: gl.VEC4}


class GlbDocument:
    """A glTF 2.0 document under construction, with its single binary buffer.

    Attributes
    ----------
    gltf : pygltflib.GLTF2, the JSON part; add meshes, nodes, materials... to it directly.
    """

    def __init__(self, generator: str = "Face Studio"):
        self.gltf = gl.GLTF2(asset=gl.Asset(generator=generator, version="2.0"))
        self._blob = bytearray()

    def add_buffer_view(self, data: bytes, target: int | None = None) -> int:
        """Append ``data`` to the buffer (4-byte aligned, as accessors require); its bufferView index."""
        self._blob += b"\0" * (-len(self._blob) % 4)
        view = gl.BufferView(buffer=0, byteOffset=len(self._blob), byteLength=len(data), target=target)
        self._blob += data
        self.gltf.bufferViews.append(view)
        return len(self.gltf.bufferViews) - 1

    def add_accessor(self, array: np.ndarray, *, target: int | None = gl.ARRAY_BUFFER, bounds: bool = False) -> int:
        """Store a ``(count,)`` or ``(count, k)`` array (k = 2, 3, 4) as an accessor; its index.

        The component type follows the dtype (float32, uint32, uint16, uint8); ``bounds`` adds
        the per-component ``min``/``max`` (required for ``POSITION`` and animation inputs).
        """
        a = np.ascontiguousarray(array)
        if a.dtype not in _COMPONENT_TYPES:
            raise ValueError(f"glTF accessors hold float32, uint32, uint16 or uint8, got {a.dtype}")
        k = 1 if a.ndim == 1 else a.shape[1]
        if a.ndim > 2 or k not in _TYPES or len(a) == 0:
            raise ValueError(f"an accessor needs a non-empty (count,) or (count, 2|3|4) array, got {a.shape}")
        acc = gl.Accessor(
            bufferView=self.add_buffer_view(a.tobytes(), target),
            componentType=_COMPONENT_TYPES[a.dtype],
            count=len(a),
            type=_TYPES[k],
        )
        if bounds:
            flat = a.reshape(len(a), k)
            acc.min = flat.min(axis=0).tolist()
            acc.max = flat.max(axis=0).tolist()
        self.gltf.accessors.append(acc)
        return len(self.gltf.accessors) - 1

    def add_png_texture(
        self, png: bytes, *, wrap_s: int = gl.CLAMP_TO_EDGE, wrap_t: int = gl.CLAMP_TO_EDGE, name: str | None = None
    ) -> int:
        """Embed PNG bytes as image + sampler (bilinear, mip-mapped) + texture; the texture index."""
        image = gl.Image(bufferView=self.add_buffer_view(png), mimeType=gl.IMAGEPNG, name=name)
        self.gltf.images.append(image)
        self.gltf.samplers.append(
            gl.Sampler(magFilter=gl.LINEAR, minFilter=gl.LINEAR_MIPMAP_LINEAR, wrapS=wrap_s, wrapT=wrap_t)
        )
        self.gltf.textures.append(
            gl.Texture(sampler=len(self.gltf.samplers) - 1, source=len(self.gltf.images) - 1, name=name)
        )
        return len(self.gltf.textures) - 1

    def to_bytes(self) -> bytes:
        """The GLB file: header, JSON chunk, BIN chunk (padded to 4 bytes with zeros)."""
        blob = bytes(self._blob) + b"\0" * (-len(self._blob) % 4)
        self.gltf.buffers = [gl.Buffer(byteLength=len(blob))]
        self.gltf.set_binary_blob(blob)
        return b"".join(self.gltf.save_to_bytes())


def encode_glb(vertices, faces, *, uv=None, texture=None, name: str = "face", unlit: bool = True) -> bytes:
    """Encode a (textured) face mesh as a binary glTF file.

    Parameters
    ----------
    vertices : (n, 3) float, positions in **mm** (head frame of :mod:`photomodel.camera`);
        written in metres.
    faces : (m, 3) int, counter-clockwise seen from outside (glTF's front faces too).
    uv : (n, 2) per-vertex or (m, 3, 2) per-corner float in [0, 1], ``v`` up, optional (with
        ``texture``). Written as ``TEXCOORD_0 = (u, 1 − v)``.
    texture : (H, W, 3|4) uint8 or float in [0, 1], row 0 = top, or bytes of a PNG file, optional
        (with ``uv``); embedded as PNG. Pass the bytes when the PNG was encoded already (the
        texture job writes the same PNG next to the ``.glb``): encoding a 1024² texture again
        costs tens of milliseconds.
    name : str, the mesh's and node's name.
    unlit : bool, also declare ``KHR_materials_unlit`` on the material (see module notes).

    Returns
    -------
    bytes
        the ``.glb`` file.
    """
    doc = GlbDocument()
    add_face_mesh(doc, vertices, faces, uv=uv, texture=texture, name=name, unlit=unlit)
    doc.gltf.scenes.append(gl.Scene(nodes=[len(doc.gltf.nodes) - 1]))
    doc.gltf.scene = 0
    return doc.to_bytes()


def add_face_mesh(
    doc: GlbDocument, vertices, faces, *, uv=None, texture=None, name: str = "face", unlit: bool = True
) -> tuple[gl.Primitive, np.ndarray]:
    """Add the (textured) face to ``doc`` as one mesh and one node (:func:`encode_glb`'s parameters).

    Returns the triangle primitive and ``source`` (n',) int: the mesh vertex each file vertex is
    (vertices ``0 … n−1`` in order, then the seam copies), for attributes added later (morph
    targets: ``delta[source]``).
    """
    v, f = check_mesh(vertices, faces)
    if (uv is None) != (texture is None):
        raise ValueError("give both uv and texture for a textured glb, or neither")
    normals = vertex_normals(v, f)
    normals[~np.any(normals, axis=1)] = (0.0, 0.0, 1.0)  # unused vertices: glTF wants unit normals
    attributes = gl.Attributes()
    pbr = gl.PbrMetallicRoughness(metallicFactor=0.0, roughnessFactor=1.0)
    source = np.arange(len(v))
    if uv is not None:
        t = check_uv(uv, len(v), len(f))
        source, uv_out, f = split_uv_seams(len(v), f, t)
        v, normals = v[source], normals[source]
        texcoord = np.column_stack([uv_out[:, 0], 1.0 - uv_out[:, 1]]).astype(np.float32)
        attributes.TEXCOORD_0 = doc.add_accessor(texcoord)
        pbr.baseColorTexture = gl.TextureInfo(index=doc.add_png_texture(_texture_png(texture), name=f"{name}_texture"))
    else:
        pbr.baseColorFactor = [0.8, 0.8, 0.8, 1.0]
    attributes.POSITION = doc.add_accessor((v * METRES_PER_MM).astype(np.float32), bounds=True)
    attributes.NORMAL = doc.add_accessor(normals.astype(np.float32))
    indices = doc.add_accessor(f.reshape(-1).astype(np.uint32), target=gl.ELEMENT_ARRAY_BUFFER)

    material = gl.Material(name=f"{name}_material", pbrMetallicRoughness=pbr, doubleSided=True)
    if unlit:
        material.extensions = {UNLIT: {}}
        if UNLIT not in doc.gltf.extensionsUsed:
            doc.gltf.extensionsUsed.append(UNLIT)
    doc.gltf.materials.append(material)
    primitive = gl.Primitive(
        attributes=attributes, indices=indices, material=len(doc.gltf.materials) - 1, mode=gl.TRIANGLES
    )
    doc.gltf.meshes.append(gl.Mesh(name=name, primitives=[primitive]))
    doc.gltf.nodes.append(gl.Node(name=name, mesh=len(doc.gltf.meshes) - 1))
    return primitive, source


#: The eight bytes every PNG file starts with (PNG spec §5.2).
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _texture_png(texture) -> bytes:
    """The PNG bytes of ``encode_glb``'s ``texture``: given bytes as they are, an array encoded."""
    if isinstance(texture, (bytes, bytearray, memoryview)):
        png = bytes(texture)
        if not png.startswith(PNG_SIGNATURE):
            raise ValueError("texture bytes must be a PNG file (they do not start with the PNG signature)")
        return png
    return encode_png(check_texture(texture))


def write_glb(
    path: str | os.PathLike, vertices, faces, *, uv=None, texture=None, name: str = "face", unlit: bool = True
) -> Path:
    """:func:`encode_glb` written atomically to ``path`` (``*.glb``); returns the path."""
    path = Path(path)
    if path.suffix.lower() != ".glb":
        raise ValueError(f"{path}: a binary glTF file name must end in .glb")
    return atomic_write_bytes(path, encode_glb(vertices, faces, uv=uv, texture=texture, name=name, unlit=unlit))
