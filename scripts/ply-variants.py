#!/usr/bin/env python3
"""Write the PLY layouts beside 3DGS's from a 3DGS PLY, for timing their readers
(scripts/formats-compare.sh). Usage: ply-variants.py IN.ply OUTDIR -> OUTDIR/NAME.{2dgs,mip,rgb}.ply

- NAME.2dgs.ply: 2DGS's layout (`scale_0 scale_1`, `scale_2` dropped; the values are not
  flattened, which changes no reader's work).
- NAME.mip.ply: Mip-Splatting's layout, `filter_3D` appended (a tenth of the smallest scale).
- NAME.rgb.ply: `red green blue` (uchar, the DC colour) in place of `f_dc_0..2`.

Standard library only (no numpy on the measuring machines)."""
import array
import math
import struct
import sys

C0 = 0.28209479177387814


def main(src, outdir):
    data = open(src, "rb").read()
    end = data.index(b"end_header\n") + 11
    head = data[:end].decode()
    lines = head.splitlines()
    if "format binary_little_endian 1.0" not in lines:
        sys.exit(f"{src}: not a binary little-endian PLY")
    n = int(next(l for l in lines if l.startswith("element vertex")).split()[2])
    props = [l.split()[2] for l in lines if l.startswith("property float")]
    if len(props) != sum(l.startswith("property") for l in lines):
        sys.exit(f"{src}: every vertex property must be float")
    k = len(props)
    a = array.array("f")
    a.frombytes(data[end : end + 4 * k * n])
    if sys.byteorder != "little":
        a.byteswap()
    name = src.rsplit("/", 1)[-1][: -len(".ply")]
    idx = {p: i for i, p in enumerate(props)}

    def write(path, names, types, payload):
        h = "ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % n
        h += "".join("property %s %s\n" % (t, nm) for nm, t in zip(names, types))
        h += "end_header\n"
        with open(path, "wb") as f:
            f.write(h.encode())
            f.write(payload)

    def floats(v):
        if sys.byteorder != "little":
            v.byteswap()
        return v.tobytes()

    keep = [p for p in props if p != "scale_2"]
    sel = [idx[p] for p in keep]
    out = array.array("f", (a[i * k + j] for i in range(n) for j in sel))
    write(f"{outdir}/{name}.2dgs.ply", keep, ["float"] * len(keep), floats(out))

    s0 = idx["scale_0"]
    out = array.array("f")
    for i in range(n):
        r = a[i * k : (i + 1) * k]
        out.extend(r)
        out.append(0.1 * math.exp(min(r[s0], r[s0 + 1], r[s0 + 2])))
    mp = props + ["filter_3D"]
    write(f"{outdir}/{name}.mip.ply", mp, ["float"] * len(mp), floats(out))

    rp = [p for p in props if not p.startswith("f_dc")]
    pk = struct.Struct("<" + "f" * 3 + "BBB" + "f" * (len(rp) - 3))
    d0 = idx["f_dc_0"]
    others = [idx[p] for p in rp[3:]]
    buf = bytearray()
    for i in range(n):
        r = a[i * k : (i + 1) * k]
        c = [max(0, min(255, round((0.5 + C0 * r[d0 + j]) * 255))) for j in range(3)]
        buf += pk.pack(r[0], r[1], r[2], *c, *(r[j] for j in others))
    names = rp[:3] + ["red", "green", "blue"] + rp[3:]
    types = ["float"] * 3 + ["uchar"] * 3 + ["float"] * (len(rp) - 3)
    write(f"{outdir}/{name}.rgb.ply", names, types, bytes(buf))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
