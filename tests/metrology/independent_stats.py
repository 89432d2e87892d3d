#!/usr/bin/env python3
"""An independent reading of the real scans, for tests/metrology/real_scans_test.cpp: plain Python 3 (zipfile,
gzip, struct, xml.etree; no numpy, nothing from vmsim), written from the formats' descriptions, printing one JSON
object. It is the reference where Gwyddion cannot read a file (an X3P under a folder of its zip, text grids whose
header Gwyddion's importer does not parse headless, Dektak CSV exports).

  independent_stats.py x3p FILE            the one main.xml of the zip (wherever it sits), its data.bin
  independent_stats.py matrix FILE         a text matrix (gzip or not) with its header's spacing and height factor
  independent_stats.py dektak FILE [X0 X1] a Dektak CSV profile (the samples with x in [X0, X1], x in the file's
                                           unit), ISO 21920-2 parameters after removing the least-squares line,
                                           5 sections

Heights are reported in metres (profiles in the file's height unit, micrometres for Dektak), lengths likewise.
"""
import gzip
import json
import math
import re
import struct
import sys
import xml.etree.ElementTree as ET
import zipfile


def moments(values):
    n = len(values)
    mean = sum(values) / n
    d = [v - mean for v in values]
    m2 = sum(x * x for x in d) / n
    sq = math.sqrt(m2)
    return {"points": n, "mean": mean, "Sq": sq,
            "Ssk": sum(x ** 3 for x in d) / n / sq ** 3, "Sku": sum(x ** 4 for x in d) / n / m2 ** 2}


def local(tag):
    return tag.split('}')[-1]


def find(node, *path):
    for name in path:
        node = next((c for c in node if local(c.tag) == name), None)
        if node is None:
            return None
    return node


def x3p(path):
    z = zipfile.ZipFile(path)
    names = [n for n in z.namelist() if n.split('/')[-1].lower() == 'main.xml' and not n.startswith('__MACOSX/')]
    if len(names) != 1:
        raise SystemExit("expected one main.xml, found %r" % names)
    folder = names[0][:-len('main.xml')]
    root = ET.fromstring(z.read(names[0]))
    axes = find(root, 'Record1', 'Axes')
    out = {"folder": folder}
    for ax in ('CX', 'CY'):
        a = find(axes, ax)
        inc, off = find(a, 'Increment'), find(a, 'Offset')
        out[ax + "_increment_m"] = float(inc.text)
        out[ax + "_offset_m"] = float(off.text) if off is not None and off.text and off.text.strip() else 0.0
    cz = find(axes, 'CZ')
    dtype = find(cz, 'DataType').text.strip()
    inc = find(cz, 'Increment')
    scale = float(inc.text) if inc is not None and inc.text and inc.text.strip() else 1.0
    dim = find(root, 'Record3', 'MatrixDimension')
    nx, ny = int(find(dim, 'SizeX').text), int(find(dim, 'SizeY').text)
    link = find(root, 'Record3', 'DataLink', 'PointDataLink').text.strip()
    raw = z.read(folder + link)
    code = {'I': 'h', 'L': 'i', 'F': 'f', 'D': 'd'}[dtype]
    vals = struct.unpack('<%d%s' % (nx * ny, code), raw)
    out.update({"nx": nx, "ny": ny, "nan": sum(1 for v in vals if math.isnan(v)),
                "inf": sum(1 for v in vals if math.isinf(v))})
    out.update(moments([v * scale for v in vals if math.isfinite(v)]))
    return out


def matrix(path):
    opener = gzip.open if path.endswith('.gz') else open
    with opener(path, 'rb') as f:
        text = f.read().decode('latin-1')
    rows, header = [], {}
    for line in text.splitlines():
        t = line.strip().lstrip('#').strip()
        if not t:
            continue
        try:
            rows.append([float(v) for v in t.split()])
            continue
        except ValueError:
            pass
        for m in re.finditer(r'([A-Za-z][^=:]*?)\s*[=:]\s*(\S+(?:\s+[^\s=]+(?=\s*$))?)', t):
            header[m.group(1).strip().lower()] = m.group(2).strip()
    units = {'m': 1.0, 'mm': 1e-3, 'um': 1e-6, '\u00b5m': 1e-6, '\xc2\xb5m': 1e-6, 'nm': 1e-9}
    factor, z_unit = 1.0, 1.0
    for k, v in header.items():
        if k.startswith('height conversion factor'):
            factor = float(v)
    if 'value units' in header:
        z_unit = units[header['value units']]
    vals = [v * factor * z_unit for r in rows for v in r if math.isfinite(v)]
    out = {"rows": len(rows), "columns": len(rows[0]), "header": header}
    out.update(moments(vals))
    return out


def dektak(path, x_from=None, x_to=None):
    lines = open(path, 'rb').read().decode('latin-1').splitlines()
    start = next(i for i, l in enumerate(lines) if l.startswith('Lateral'))
    xs, zs = [], []
    for l in lines[start + 1:]:
        f = l.split(',')
        if len(f) < 2 or not f[0].strip():
            break
        xs.append(float(f[0]))
        zs.append(float(f[1]))
    n_all = len(xs)
    # The stylus samples uniformly; the export prints the positions rounded (to 0.1 um). The uniform grid they
    # stand for: least squares of x against the index. The heights are placed on it (the profile rises 16 um over
    # 1.5 mm: a 0.05 um rounding of x would move the least-squares line by up to 0.5 nm).
    mi, mx = (n_all - 1) / 2, sum(xs) / n_all
    dx = sum((i - mi) * (x - mx) for i, x in enumerate(xs)) / sum((i - mi) ** 2 for i in range(n_all))
    xs = [mx + (i - mi) * dx for i in range(n_all)]
    if x_from is not None:
        keep = [i for i, x in enumerate(xs) if x_from <= x <= x_to]
        xs, zs = [xs[i] for i in keep], [zs[i] for i in keep]
    n = len(zs)
    ax, az = sum(xs) / n, sum(zs) / n
    b = sum((x - ax) * (z - az) for x, z in zip(xs, zs)) / sum((x - ax) ** 2 for x in xs)
    r = [z - az - b * (x - ax) for x, z in zip(xs, zs)]
    mean = sum(r) / n
    r = [v - mean for v in r]
    rq = math.sqrt(sum(v * v for v in r) / n)
    sections = [r[k * n // 5:(k + 1) * n // 5] for k in range(5)]
    return {"points_in_file": n_all, "dx": dx, "points": n, "Ra": sum(abs(v) for v in r) / n, "Rq": rq,
            "Rsk": sum(v ** 3 for v in r) / n / rq ** 3, "Rku": sum(v ** 4 for v in r) / n / rq ** 4,
            "Rp": sum(max(s) for s in sections) / 5, "Rv": sum(-min(s) for s in sections) / 5,
            "Rz": sum(max(s) - min(s) for s in sections) / 5, "Rt": max(r) - min(r)}


if __name__ == '__main__':
    mode, path = sys.argv[1], sys.argv[2]
    if mode == 'x3p':
        result = x3p(path)
    elif mode == 'matrix':
        result = matrix(path)
    elif mode == 'dektak':
        result = dektak(path, *(float(a) for a in sys.argv[3:5])) if len(sys.argv) > 4 else dektak(path)
    else:
        raise SystemExit("unknown mode " + mode)
    print(json.dumps(result))
