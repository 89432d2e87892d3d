"""Comparing two result directories file by file (byte for byte; X3P entry by entry without dates; report.json without timings)."""
import json
import re
import zipfile

# report.json keys that differ between two runs of the same job by nature: times, memory, hashes and paths of inputs.
VOLATILE = {"timings_s", "removal_cpu", "peak_rss_bytes", "cpu_s"}


def x3p_payload(path):
    """Every entry of an X3P file but the checksum, with main.xml's dates removed (they record when it was written)."""
    with zipfile.ZipFile(path) as z:
        out = {}
        for n in sorted(z.namelist()):
            if n == "md5checksum.hex":
                continue
            data = z.read(n)
            if n == "main.xml":
                data = re.sub(rb"<(Date|CalibrationDate)>[^<]*<", rb"<\1><", data)
            out[n] = data
        return out


def clean_report(j):
    if isinstance(j, dict):
        return {k: clean_report(v) for k, v in j.items() if k not in VOLATILE}
    if isinstance(j, list):
        return [clean_report(x) for x in j]
    return j


def differences(dir_a, dir_b):
    """The files that differ between two result directories (report.html and report.json's volatile keys aside)."""
    names_a = sorted(p.name for p in dir_a.iterdir())
    names_b = sorted(p.name for p in dir_b.iterdir())
    diffs = []
    if names_a != names_b:
        diffs.append(f"file lists differ: {names_a} vs {names_b}")
    for name in names_a:
        if name not in names_b or name == "report.html":
            continue
        if name == ".vmsim-output":  # core/output_dir's marker names its writer ("vmsim run" or "vmsim run (Python)")
            continue
        a, b = dir_a / name, dir_b / name
        if name.endswith(".x3p"):
            if x3p_payload(a) != x3p_payload(b):
                diffs.append(name)
        elif name == "report.json":
            ra, rb = clean_report(json.loads(a.read_text())), clean_report(json.loads(b.read_text()))
            if ra != rb:
                keys = sorted(k for k in set(ra) | set(rb) if ra.get(k) != rb.get(k))
                diffs.append(f"report.json differs in {keys}")
        elif a.read_bytes() != b.read_bytes():
            diffs.append(name)
    return diffs
