#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Regenerate the malformed-input corpus in tests/bad/.

Every file written here must be REJECTED by `occswitch info FILE` with one line
`error: FILE: what` on stderr and exit status 2.  expect.txt maps each file to a
lowercase substring that `what` must contain; README.md explains each case.

Deterministic, standard library only:  python3 tests/bad/make_corpus.py
rewrites every file byte-identically (run it from anywhere).  `--check` only
verifies that the files on disk match what the script would write.

Each case starts from a correct model and breaks exactly ONE thing, so that a
rejection can only be caused by the defect under test.  The self-checks at the
bottom (run on every invocation) assert the intended defect is present.
"""

import base64
import copy
import hashlib
import json
import math
import os
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))

# name -> (bytes, expected substring, what is wrong)
CASES = {}


def case(name, data, expect, what):
    assert name not in CASES, name
    assert isinstance(data, (bytes, bytearray)), name
    assert expect == expect.lower(), name
    assert len(data) < 20 * 1024, name
    CASES[name] = (bytes(data), expect, what)


# ---------------------------------------------------------------- helpers

F32_NAN = struct.unpack("<f", struct.pack("<I", 0x7FC00000))[0]  # quiet NaN
F32_INF = struct.unpack("<f", struct.pack("<I", 0x7F800000))[0]  # +infinity

TRI = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]


def pad4(b, fill):
    return b + fill * ((4 - len(b) % 4) % 4)


def garbage(seed, n):
    """Deterministic pseudo-random bytes (SHA-256 in counter mode)."""
    out = b""
    i = 0
    while len(out) < n:
        out += hashlib.sha256(seed + struct.pack("<I", i)).digest()
        i += 1
    return out[:n]


def pack_positions(points):
    return b"".join(struct.pack("<3f", *p) for p in points)


def base_bin(points=TRI, indices=(0, 1, 2), index_fmt="H"):
    """POSITION floats followed by the index array, padded to 4 bytes."""
    pos = pack_positions(points)
    idx = struct.pack("<%d%s" % (len(indices), index_fmt), *indices)
    return pos, pad4(pos + idx, b"\x00")


def base_gltf(points=TRI, indices=(0, 1, 2)):
    """A correct one-triangle glTF 2.0 model: (json dict, bin bytes).

    accessor 0 = POSITION (VEC3 float, bufferView 0), accessor 1 = indices
    (SCALAR unsigned short, bufferView 1); one buffer; node 0 -> mesh 0; scene 0.
    """
    pos, binary = base_bin(points, indices)
    gltf = {
        "asset": {"version": "2.0", "generator": "occswitch tests/bad/make_corpus.py"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]}],
        "accessors": [
            {"bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": 3,
             "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "byteOffset": 0, "componentType": 5123, "count": 3,
             "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": len(pos), "target": 34962},
            {"buffer": 0, "byteOffset": len(pos), "byteLength": 2 * len(indices), "target": 34963},
        ],
        "buffers": [{"byteLength": len(binary)}],
    }
    return gltf, binary


def data_uri(binary):
    return "data:application/octet-stream;base64," + base64.b64encode(binary).decode("ascii")


def gltf_text(gltf, binary=None):
    """.gltf text; the buffer (if given) is embedded as a base64 data: URI."""
    g = copy.deepcopy(gltf)
    if binary is not None:
        g["buffers"][0]["uri"] = data_uri(binary)
    return (json.dumps(g, indent=1) + "\n").encode("ascii")


GLB_MAGIC = b"glTF"
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942


def glb_bytes(gltf, binary, version=2):
    j = pad4(json.dumps(gltf, separators=(",", ":")).encode("ascii"), b" ")
    b = pad4(binary, b"\x00")
    body = struct.pack("<II", len(j), CHUNK_JSON) + j + struct.pack("<II", len(b), CHUNK_BIN) + b
    return GLB_MAGIC + struct.pack("<II", version, 12 + len(body)) + body


def glb_parts(data):
    """(json_start, json_len, bin_start, bin_len) of a well-formed two-chunk GLB."""
    jlen = struct.unpack_from("<I", data, 12)[0]
    bstart = 20 + jlen
    blen = struct.unpack_from("<I", data, bstart)[0]
    return 20, jlen, bstart + 8, blen


def set_u32(data, off, value):
    data = bytearray(data)
    struct.pack_into("<I", data, off, value)
    return bytes(data)


# ---------------------------------------------------------------- GLB cases

G, B = base_gltf()
GOOD_GLB = glb_bytes(G, B)
J0, JLEN, B0, BLEN = glb_parts(GOOD_GLB)
assert (J0, BLEN, len(GOOD_GLB)) == (20, 44, B0 + 44)

junk = garbage(b"occswitch glb garbage", 96)
assert junk[:4] != GLB_MAGIC
case("glb_garbage.glb", junk, "magic",
     "96 pseudo-random bytes with a .glb extension (no glTF magic)")

case("glb_bad_magic.glb", b"glTX" + GOOD_GLB[4:], "magic",
     "valid one-triangle GLB whose magic is `glTX` instead of `glTF`")

case("glb_length_exceeds_file.glb", set_u32(GOOD_GLB, 8, len(GOOD_GLB) + 1024), "truncated",
     "valid GLB whose header length field claims 1024 bytes more than the file has")

cut = J0 + JLEN // 2
case("glb_truncated_json_chunk.glb", set_u32(GOOD_GLB[:cut], 8, cut), "truncated",
     "valid GLB cut in the middle of the JSON chunk; the 12-byte header length is patched "
     "to the new file size, so only the JSON chunk length (%d) overruns the file" % JLEN)

g = copy.deepcopy(G)
g["buffers"][0]["byteLength"] = len(B) + 4
case("glb_bin_chunk_short.glb", glb_bytes(g, B), "buffer",
     "consistent GLB whose BIN chunk holds %d bytes but buffers[0].byteLength is %d"
     % (len(B), len(B) + 4))

cut = B0 + 20
case("glb_truncated_bin.glb", GOOD_GLB[:cut], "truncated",
     "valid GLB cut 20 bytes into the 44-byte BIN chunk (header length and chunk length unchanged)")

cut = B0 + BLEN - 8
case("glb_bin_chunk_length_overclaims.glb", set_u32(GOOD_GLB[:cut], 8, cut), "truncated",
     "valid GLB with the last 8 bytes of the BIN chunk cut off and the header length patched "
     "to the new file size; the BIN chunk length still says 44 but only 36 bytes follow")

case("glb_version_1.glb", set_u32(GOOD_GLB, 4, 1), "version",
     "valid GLB whose header version field is 1 instead of 2")

g = copy.deepcopy(G)
g["buffers"][0]["byteLength"] = 0
case("glb_buffer_bytelength_zero.glb", glb_bytes(g, B), "buffer",
     "GLB whose buffers[0].byteLength is 0 (spec minimum is 1; the buffer views then "
     "also lie outside it)")

case("glb_empty.glb", b"", "empty", "zero-byte file with a .glb extension")


# ---------------------------------------------------------------- .gltf cases

GOOD_GLTF = gltf_text(G, B)

text = GOOD_GLTF.decode("ascii")
broken = text.replace('"scene": 0,', '"scene": 0', 1)  # drop one comma
assert broken != text
case("gltf_invalid_json.gltf", broken.encode("ascii"), "json",
     "the valid one-triangle model with one comma removed (JSON syntax error)")

case("gltf_not_object.gltf", (json.dumps([json.loads(text)], indent=1) + "\n").encode("ascii"),
     "json", "valid JSON whose root is an array (holding the valid model), not an object")

g = copy.deepcopy(G)
del g["asset"]
case("gltf_missing_asset.gltf", gltf_text(g, B), "missing",
     "valid one-triangle model without the required `asset` object")

g = copy.deepcopy(G)
g["asset"]["version"] = "1.0"
case("gltf_asset_version_1.gltf", gltf_text(g, B), "version",
     "valid one-triangle model whose asset.version is \"1.0\"")

g = copy.deepcopy(G)
g["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 5
case("gltf_accessor_out_of_range.gltf", gltf_text(g, B), "accessor",
     "primitive attribute POSITION refers to accessor 5; there are 2 accessors")

g = copy.deepcopy(G)
g["accessors"][0]["byteOffset"] = 12
case("gltf_accessor_exceeds_bufferview.gltf", gltf_text(g, B), "accessor",
     "POSITION accessor has byteOffset 12: 12 + 3*12 = 48 bytes > bufferView 0 byteLength 36")

g = copy.deepcopy(G)
g["bufferViews"][1]["byteOffset"] = 40
case("gltf_bufferview_exceeds_buffer.gltf", gltf_text(g, B), "buffer",
     "bufferView 1 (indices) at byteOffset 40 length 6 ends at 46 > buffer byteLength 44")

g, b = base_gltf(indices=(0, 1, 7))
case("gltf_index_out_of_range.gltf", gltf_text(g, b), "index",
     "index buffer holds 0 1 7 but there are only 3 vertices")

g = copy.deepcopy(G)
g["buffers"][0]["uri"] = "does_not_exist.bin"
case("gltf_missing_buffer_file.gltf", gltf_text(g), "buffer",
     "buffer uri is the external file does_not_exist.bin, which does not exist")

nan_tri = [TRI[0], (F32_NAN, 0.0, 0.0), TRI[2]]
g, b = base_gltf(points=nan_tri)
case("gltf_nan_position.gltf", gltf_text(g, b), "nan",
     "vertex 1 x is a float32 quiet NaN (0x7fc00000) in the embedded buffer")

inf_tri = [TRI[0], TRI[1], (0.0, F32_INF, 0.0)]
g, b = base_gltf(points=inf_tri)
case("gltf_inf_position.gltf", gltf_text(g, b), "nan",
     "vertex 2 y is float32 +Inf (0x7f800000) in the embedded buffer; the message for any "
     "non-finite coordinate should say \"nan\" (e.g. \"non-finite (nan/inf) position\")")

g = copy.deepcopy(G)
g["nodes"] = [{"mesh": 0, "children": [1]}, {"children": [0]}]
case("gltf_node_cycle.gltf", gltf_text(g, B), "cycle",
     "node 0 (root of scene 0) has child 1, node 1 has child 0")

g = copy.deepcopy(G)
g["nodes"] = [{"mesh": 0, "children": [0]}]
case("gltf_node_self_reference.gltf", gltf_text(g, B), "cycle",
     "node 0 lists itself as its own child")

g = copy.deepcopy(G)
g["nodes"] = [{"mesh": 0, "children": [7]}]
case("gltf_node_child_out_of_range.gltf", gltf_text(g, B), "node",
     "node 0 has child 7; there is 1 node")

g = copy.deepcopy(G)
g["extensionsUsed"] = ["KHR_draco_mesh_compression"]
g["extensionsRequired"] = ["KHR_draco_mesh_compression"]
g["meshes"][0]["primitives"][0]["extensions"] = {
    "KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}
case("gltf_unsupported_required_extension.gltf", gltf_text(g, B), "extension",
     "extensionsRequired lists KHR_draco_mesh_compression and the primitive uses it "
     "(the uncompressed fallback triangle is still valid, so ignoring the requirement "
     "would wrongly accept the file)")

g = copy.deepcopy(G)
g["scenes"] = [{}]
case("gltf_empty_scene.gltf", gltf_text(g, B), "empty",
     "default scene 0 has no nodes (the mesh and node exist but are not in the scene)")

g = copy.deepcopy(G)
g["meshes"][0]["primitives"][0]["mode"] = 0
case("gltf_points_only.gltf", gltf_text(g, B), "no triangles",
     "the only primitive has mode 0 (POINTS)")

g, b = base_gltf()
pos = pack_positions(TRI)
b = pos + struct.pack("<3f", 0.0, 1.0, 2.0)
g["bufferViews"][1]["byteLength"] = 12
g["accessors"][1]["componentType"] = 5126
g["buffers"][0]["byteLength"] = len(b)
case("gltf_indices_float.gltf", gltf_text(g, b), "accessor",
     "indices accessor has componentType 5126 (FLOAT); data 0.0 1.0 2.0 fits its 12-byte view")

g = copy.deepcopy(G)
g["accessors"][0]["type"] = "VEC2"
g["accessors"][0]["min"] = [0.0, 0.0]
g["accessors"][0]["max"] = [1.0, 1.0]
case("gltf_position_vec2.gltf", gltf_text(g, B), "accessor",
     "POSITION accessor has type VEC2 (must be VEC3); 3*8 bytes fit its view")

g = copy.deepcopy(G)
g["scene"] = 3
case("gltf_scene_out_of_range.gltf", gltf_text(g, B), "index",
     "\"scene\": 3 but there is 1 scene (message e.g. \"scene index 3 out of range\")")


# ---------------------------------------------------------------- OBJ / OFF

HDR = "# occswitch tests/bad: "

case("obj_face_index_out_of_range.obj",
     (HDR + "face refers to vertex 9, there are 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").encode(),
     "index", "`f 1 2 9` with only 3 vertices")

case("obj_no_faces.obj", (HDR + "vertices only\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").encode(),
     "no triangles", "three vertices and no faces")

case("obj_nan_vertex.obj",
     (HDR + "first vertex is nan\nv nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").encode(),
     "nan", "`v nan 0 0`, otherwise a valid triangle")

case("obj_empty.obj", b"", "empty", "zero-byte .obj file")

case("off_bad_header.off", b"OFX\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "magic",
     "first line is `OFX` instead of `OFF`; the rest is a valid triangle")

case("off_truncated.off", b"OFF\n8 6 0\n0 0 0\n1 0 0\n0 1 0\n", "truncated",
     "header announces 8 vertices and 6 faces; the file ends after 3 vertices")


# ---------------------------------------------------------------- STL


def stl_binary(header_text, tris, count=None):
    header = header_text.encode("ascii")
    assert len(header) <= 80 and not header.lower().startswith(b"solid")
    header = header.ljust(80, b"\x00")
    body = b"".join(struct.pack("<12fH", 0.0, 0.0, 1.0, *(c for v in t for c in v), 0)
                    for t in tris)
    return header + struct.pack("<I", len(tris) if count is None else count) + body


TRI2 = [(1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0)]
case("stl_truncated.stl", stl_binary("occswitch tests/bad: says 12 triangles, 2 present",
                                     [TRI, TRI2], count=12),
     "truncated", "binary STL whose triangle count is 12 but only 2 triangles (100 bytes) follow")

case("stl_nan_coordinate.stl", stl_binary("occswitch tests/bad: second triangle has a nan",
                                          [TRI, [TRI2[0], (1.0, F32_NAN, 0.0), TRI2[2]]]),
     "nan", "binary STL, 2 triangles, the second one's vertex 1 y is a float32 NaN")


# ---------------------------------------------------------------- PLY

PLY_BIN_HEADER = (b"ply\nformat binary_little_endian 1.0\n"
                  b"comment occswitch tests/bad: body cut after 20 of 49 bytes\n"
                  b"element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                  b"element face 1\nproperty list uchar int vertex_indices\nend_header\n")
ply_body = pack_positions(TRI) + struct.pack("<B3i", 3, 0, 1, 2)
assert len(ply_body) == 49
case("ply_truncated_binary.ply", PLY_BIN_HEADER + ply_body[:20], "truncated",
     "binary little-endian PLY (3 vertices, 1 face = 49 body bytes) cut after 20 body bytes")


def ply_ascii(face, first_line=b"ply"):
    return (first_line + b"\nformat ascii 1.0\n"
            b"element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            b"element face 1\nproperty list uchar int vertex_indices\nend_header\n"
            b"0 0 0\n1 0 0\n0 1 0\n" + face + b"\n")


case("ply_face_index_out_of_range.ply", ply_ascii(b"3 0 1 9"), "index",
     "ASCII PLY, 3 vertices, face `3 0 1 9`")

case("ply_garbage_header.ply", ply_ascii(b"3 0 1 2", first_line=garbage(b"occswitch ply", 12)
                                         .replace(b"\n", b"?").replace(b"\r", b"?")),
     "magic", "valid ASCII PLY whose first line `ply` is replaced by 12 bytes of binary garbage")


# ---------------------------------------------------------------- found by fuzzing
# Inputs libFuzzer found (launch/fuzz-run), kept as they were found.

case("ply_fuzz_openmesh_crash.ply", b'ply\nformat binary_little_endian 1.0\ncomment occswitch tesperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uihar int vertex_indices\nend_header\n0 0 0 1\nproperty list uchar int vertex face 1\nproperty list uc\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x80?\x00\x00\x00\x00', "property",
     "binary PLY header mangled by the fuzzer (a property line before any element): OpenMesh's "
     "PLY reader wrote through a wild pointer on it (SEGV in _PLYReader_::can_u_read)")

case("ply_fuzz_huge_index.ply", b'ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 2 0\n0 1 0\n2 0 0\n3 0 0 2\n4 1 4 2 888888888888888888888888888888888888888888888888888888888888888888883\n', "index",
     "ASCII PLY whose face lists a vertex index of 8.9e68: our reader converted it to an integer "
     "for its message (undefined behaviour, found by UBSan under libFuzzer)")

case("stl_empty.stl", b"", "truncated",
     "an empty .stl: OpenMesh's STL reader leaked 32 bytes on it")


# ---------------------------------------------------------------- other

case("model.xyz", b"0 0 0\n1 0 0\n0 1 0\n", "extension",
     "unknown file extension .xyz (the content is a plain point list)")


# ---------------------------------------------------------------- README.md

README_HEAD = """\
# tests/bad: malformed model files

Every file here must be **rejected**: `occswitch info FILE` prints exactly one
line `error: FILE: what` on stderr and exits with status 2 (no crash, no hang,
no other output on stderr).  `expect.txt` lists `FILENAME<TAB>SUBSTRING`; the
test checks the `error: <path>:` prefix and that `what` contains SUBSTRING,
case-insensitively.  Substrings are drawn from a small vocabulary on purpose
(truncated, magic, json, accessor, buffer, index, missing, nan, cycle,
extension, no triangles, version, empty, node) so as not to fix the wording.
Note: `index` is not a substring of `indices`, and non-finite values (NaN *and*
Inf) are expected to be reported with the word `nan` (e.g. "non-finite (nan/inf)
position").

All files are generated by `make_corpus.py` (standard library only,
deterministic): `python3 tests/bad/make_corpus.py` rewrites them byte-identically,
`python3 tests/bad/make_corpus.py --check` fails if a file differs.  Each case
starts from a correct one-triangle model (positions (0,0,0) (1,0,0) (0,1,0),
indices 0 1 2) and breaks exactly one thing; `.gltf` files embed their buffer as
a base64 `data:` URI so they are self-contained (except the missing-buffer case).

| file | what is wrong | message contains |
| --- | --- | --- |
"""

README_TAIL = """
## What the libraries do on their own (tinygltf 2.7.0, OpenMesh 9.0, Debian)

Observed with a probe built with `-fsanitize=address,undefined`; the importer
has to add the checks marked "accepts".

| file | library result |
| --- | --- |
| glb_bin_chunk_length_overclaims.glb | **tinygltf heap over-read** (memcpy of 44 bytes from a 36-byte tail): its check `chunk1_length + 20 + jsonLength <= length` forgets the 8-byte chunk header. Validate the GLB chunk layout before calling tinygltf. |
| glb_buffer_bytelength_zero.glb | **tinygltf throws std::out_of_range** (`buffer->data.at(0)` on an empty vector). Catch exceptions around the load, or pre-check byteLength >= 1. |
| glb_length_exceeds_file.glb, glb_truncated_bin.glb, glb_truncated_json_chunk.glb | rejected as "Invalid glTF binary." (no word about truncation) |
| glb_bad_magic.glb, glb_garbage.glb | rejected, "Invalid magic." |
| glb_bin_chunk_short.glb | rejected, "Invalid `byteLength'..." |
| glb_empty.glb | rejected, "File is empty" |
| glb_version_1.glb, gltf_asset_version_1.gltf | accepts (version not checked) |
| gltf_invalid_json.gltf, gltf_not_object.gltf, gltf_missing_asset.gltf, gltf_missing_buffer_file.gltf | rejected |
| all other gltf_*.gltf | accepts: no check of accessor/bufferView/buffer ranges, attribute accessor indices, index values, node/scene indices, node cycles (a naive recursive traversal overflows the stack), NaN/Inf, component types, accessor types, primitive modes, extensionsRequired |
| obj_face_index_out_of_range.obj, ply_face_index_out_of_range.ply | OpenMesh returns **true** with 0 faces (face dropped) and prints a diagnostic **on stderr** |
| obj_nan_vertex.obj | OpenMesh returns true, silently **drops** the `v nan` line (2 vertices), then drops the face as out of range: the NaN is never visible in the mesh |
| stl_nan_coordinate.stl | OpenMesh returns true with **1 face**: the triangle with the NaN vertex is silently dropped (its vertex-merging map does not cope with NaN, which breaks the map's ordering); NaN never reaches the mesh |
| stl_truncated.stl | OpenMesh returns true with 0 vertices (size does not match 84+50n, so it is parsed as ASCII STL) |
| off_truncated.off | OpenMesh returns true with 4 vertices, 0 faces, and prints diagnostics on stderr |
| obj_empty.obj, obj_no_faces.obj | OpenMesh returns true with 0 faces |
| off_bad_header.off, ply_garbage_header.ply, ply_truncated_binary.ply, model.xyz | OpenMesh returns false (only a bool; truncated PLY prints on stderr) |

OpenMesh writes its diagnostics to stderr through `omerr()`/`omlog()`; disable
them (e.g. `omerr().disable()`) or the one-line-on-stderr rule breaks.
"""


def readme():
    rows = "".join("| `%s` | %s | `%s` |\n" % (n, w, e) for n, (_, e, w) in sorted(CASES.items()))
    assert "|" not in "".join(w for _, _, w in CASES.values())
    return (README_HEAD + rows + README_TAIL).encode("utf-8")


# ---------------------------------------------------------------- self-checks


def check():
    good = json.loads(GOOD_GLTF)
    # The base models are correct (structurally) so each case has one defect.
    assert struct.unpack_from("<4sII", GOOD_GLB) == (b"glTF", 2, len(GOOD_GLB))
    assert json.loads(GOOD_GLB[J0:J0 + JLEN]) == G
    assert base64.b64decode(good["buffers"][0]["uri"].split(",", 1)[1]) == B
    assert B[:36] == pack_positions(TRI) and struct.unpack_from("<3H", B, 36) == (0, 1, 2)

    for name, (data, _, _) in CASES.items():
        if name.endswith(".gltf"):
            if name == "gltf_invalid_json.gltf":
                try:
                    json.loads(data)
                except json.JSONDecodeError:
                    continue
                raise AssertionError(name + " parses")
            doc = json.loads(data)
            if name == "gltf_not_object.gltf":
                assert isinstance(doc, list)
                continue
            assert isinstance(doc, dict), name
            buf = doc["buffers"][0]
            if buf["uri"].startswith("data:"):
                raw = base64.b64decode(buf["uri"].split(",", 1)[1])
                assert len(raw) == buf["byteLength"], name  # tinygltf requires equality
                floats = struct.unpack_from("<9f", raw, 0)
                finite = all(math.isfinite(f) for f in floats)
                assert finite == (name not in ("gltf_nan_position.gltf",
                                               "gltf_inf_position.gltf")), name
        elif name.endswith(".glb") and len(data) >= 20 and data[:4] == b"glTF":
            jlen = struct.unpack_from("<I", data, 12)[0]
            if 20 + jlen <= len(data):
                json.loads(data[20:20 + jlen])  # JSON chunk itself is fine

    def embedded(n):
        uri = json.loads(CASES[n][0])["buffers"][0]["uri"]
        return base64.b64decode(uri.split(",", 1)[1])
    assert math.isnan(struct.unpack_from("<f", embedded("gltf_nan_position.gltf"), 12)[0])
    assert math.isinf(struct.unpack_from("<f", embedded("gltf_inf_position.gltf"), 28)[0])
    stl = CASES["stl_nan_coordinate.stl"][0]
    assert len(stl) == 84 + 2 * 50
    assert math.isnan(struct.unpack_from("<f", stl, 84 + 50 + 12 + 12 + 4)[0])
    stl = CASES["stl_truncated.stl"][0]
    assert struct.unpack_from("<I", stl, 80)[0] == 12 and len(stl) == 84 + 100
    assert b"\n" not in CASES["ply_garbage_header.ply"][0][:12]
    assert not CASES["ply_garbage_header.ply"][0].startswith(b"ply")

    # glb_bin_chunk_short: consistent container, only byteLength is too big.
    d = CASES["glb_bin_chunk_short.glb"][0]
    _, jl, bs, bl = glb_parts(d)
    assert len(d) == bs + bl == struct.unpack_from("<I", d, 8)[0]
    assert json.loads(d[20:20 + jl])["buffers"][0]["byteLength"] == bl + 4
    # glb_bin_chunk_length_overclaims: header length == file size, BIN chunk overruns by 8.
    d = CASES["glb_bin_chunk_length_overclaims.glb"][0]
    _, jl, bs, bl = glb_parts(d)
    assert struct.unpack_from("<I", d, 8)[0] == len(d) and bs + bl == len(d) + 8
    # glb_truncated_json_chunk: header length == file size, JSON chunk overruns.
    d = CASES["glb_truncated_json_chunk.glb"][0]
    assert struct.unpack_from("<I", d, 8)[0] == len(d) < 20 + struct.unpack_from("<I", d, 12)[0]

    # Graph defects really are what they claim.
    def doc(n):
        return json.loads(CASES[n][0])
    assert doc("gltf_node_cycle.gltf")["nodes"][1]["children"] == [0]
    assert doc("gltf_scene_out_of_range.gltf")["scene"] >= len(doc("gltf_scene_out_of_range.gltf")["scenes"])
    d = doc("gltf_accessor_out_of_range.gltf")
    assert d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] >= len(d["accessors"])
    d = doc("gltf_accessor_exceeds_bufferview.gltf")
    a = d["accessors"][0]
    assert a["byteOffset"] + a["count"] * 12 > d["bufferViews"][0]["byteLength"]
    d = doc("gltf_bufferview_exceeds_buffer.gltf")
    v = d["bufferViews"][1]
    assert v["byteOffset"] + v["byteLength"] > d["buffers"][0]["byteLength"]
    assert "does_not_exist.bin" not in os.listdir(HERE)


def main(argv):
    check()
    only_check = "--check" in argv
    stale = []
    for name, (data, _, _) in sorted(CASES.items()):
        path = os.path.join(HERE, name)
        old = open(path, "rb").read() if os.path.exists(path) else None
        if old != data:
            stale.append(name)
            if not only_check:
                with open(path, "wb") as f:
                    f.write(data)
    expect = "".join("%s\t%s\n" % (n, e) for n, (_, e, _) in sorted(CASES.items())).encode()
    for name, data in (("expect.txt", expect), ("README.md", readme())):
        path = os.path.join(HERE, name)
        old = open(path, "rb").read() if os.path.exists(path) else None
        if old != data:
            stale.append(name)
            if not only_check:
                with open(path, "wb") as f:
                    f.write(data)
    if only_check and stale:
        print("stale: " + " ".join(stale), file=sys.stderr)
        return 1
    print("%d cases%s" % (len(CASES), (", rewrote: " + " ".join(stale)) if stale and not only_check else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
