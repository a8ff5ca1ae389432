#!/usr/bin/env python3
"""Writes the PLY seeds of fuzz/corpus/ply/ (make_seeds.sh runs it): small meshes in the three
formats with what the reader skips (colours, lists, other elements), and broken ones."""
import os
import struct
import sys

TYPES = {"char": "b", "uchar": "B", "short": "h", "ushort": "H", "int": "i", "uint": "I",
         "float": "f", "double": "d", "int8": "b", "uint8": "B", "int16": "h", "uint16": "H",
         "int32": "i", "uint32": "I", "float32": "f", "float64": "d"}


def ply(fmt, elements, extra=""):
    """elements: (name, [property declarations], [records of values, lists as length + items])."""
    head = ["ply", "format %s 1.0" % fmt, "comment rayfarm fuzz seed"] + ([extra] if extra else [])
    for name, props, rows in elements:
        head.append("element %s %d" % (name, len(rows)))
        head += ["property " + p for p in props]
    head.append("end_header")
    out = ("\n".join(head) + "\n").encode()
    order = "<" if fmt == "binary_little_endian" else ">"
    for _, props, rows in elements:
        for row in rows:
            values, words, i = [], [], 0
            for p in props:
                parts = p.split()
                if parts[0] == "list":
                    n = row[i]
                    values.append((parts[1], n))
                    values += [(parts[2], v) for v in row[i + 1:i + 1 + n]]
                    i += 1 + n
                else:
                    values.append((parts[0], row[i]))
                    i += 1
            if fmt == "ascii":
                out += (" ".join(str(v) for _, v in values) + "\n").encode()
            else:
                for t, v in values:
                    out += struct.pack(order + TYPES[t], v)
    return out


def cube():
    vertices, faces = [], []
    for i in range(8):
        x, y, z = i & 1, (i >> 1) & 1, (i >> 2) & 1
        vertices.append([x, y, z, 2 * x - 1, 2 * y - 1, 2 * z - 1, x, y])
    for q in ([0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]):
        faces.append([4] + q)
    return vertices, faces


def main(folder):
    os.makedirs(folder, exist_ok=True)
    v, f = cube()
    xyz_n_uv = ["float x", "float y", "float z", "float nx", "float ny", "float nz", "float u",
                "float v"]
    seeds = {
        "cube-ascii.ply": ply("ascii", [("vertex", xyz_n_uv, v), ("face", ["list uchar int vertex_indices"], f)],
                              "obj_info a cube"),
        "cube-le.ply": ply("binary_little_endian", [
            ("vertex", ["float x", "float y", "float z", "uchar red", "list uchar float extra"],
             [r[:3] + [200, 1, 0.5] for r in v]),
            ("face", ["list uchar uint vertex_indices", "uchar flags"], [q + [1] for q in f]),
            ("edge", ["int vertex1", "int vertex2"], [[0, 1], [1, 2]]),
            ("material", ["list ushort double k"], [[2, 0.1, 0.2]])]),
        "tri-be.ply": ply("binary_big_endian", [
            ("face", ["list int ushort vertex_index"], [[3, 0, 1, 2], [5, 0, 1, 2, 3, 4]]),
            ("vertex", ["double x", "short y", "char z", "float texture_u", "float texture_v"],
             [[0, 0, 0, 0, 0], [1, 0, 0, 1, 0], [1, 1, 0, 1, 1], [0, 1, 0, 0, 1], [-1, 0, 0, 0, 0]])]),
    }
    tri = [("vertex", ["float x", "float y", "float z"], [[0, 0, 0], [1, 0, 0], [0, 1, 0]]),
           ("face", ["list uchar int vertex_indices"], [[3, 0, 1, 2]])]
    le = ply("binary_little_endian", tri)
    seeds["trailing-le.ply"] = le + b"trailing bytes"
    seeds["truncated-le.ply"] = le[:-3]
    seeds["lying-count.ply"] = le.replace(b"element vertex 3", b"element vertex 4000000000")
    seeds["negative-list.ply"] = ply("binary_big_endian", [
        ("vertex", ["float x", "float y", "float z"], [[0, 0, 0], [1, 0, 0], [0, 1, 0]]),
        ("face", ["list char int vertex_indices"], [[3, 0, 1, 2]])]).replace(b"\x03\x00\x00\x00\x00", b"\xfd\x00\x00\x00\x00")
    seeds["no-format.ply"] = ply("ascii", tri).replace(b"format ascii 1.0\n", b"")
    for name, data in seeds.items():
        with open(os.path.join(folder, name), "wb") as out:
            out.write(data)


if __name__ == "__main__":
    main(sys.argv[1])
