#!/usr/bin/env python3
"""Checks a result directory's report.html against its report.json (or study.json), independently of vmsim's code.

  check_report_html.py DIR [--pictures yes|no] [--note TEXT ...]

- Valid HTML5: html5lib's parser in strict mode (every parse error of the WHATWG HTML parsing algorithm is an error),
  and Debian's tidy (errors and warnings) when it is installed.
- Self-contained: no script, no external style sheet, frame or object; every link and picture is a relative path
  inside DIR that exists there (or a '#fragment' whose id exists); every <img> is a PNG file.
- The same facts as the JSON: every number of the JSON is on the page as a data-value (the JSON's own value), and
  every string is in the page's text or attributes; the key figures (the deepest mark's depth, the cycle time, ...)
  are shown as the page's reader sees them, formatted here from the JSON.
- --pictures yes: every PNG of DIR/images is shown; no: the page shows none. --note TEXT: the page says TEXT.
Exit status 0: all checks hold; 1: some failed (listed); 77: html5lib is not installed (the test is skipped).
"""
import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import urllib.parse

try:
    import html5lib
except ImportError:
    print("html5lib is not installed (Debian: python3-html5lib; scripts/install-deps.sh --test): not checked")
    sys.exit(77)

failures = []


def fail(msg):
    failures.append(msg)


def leaves(v, path=()):
    """(path, value) of every scalar in a JSON value."""
    if isinstance(v, dict):
        for k, x in v.items():
            yield from leaves(x, path + (k,))
    elif isinstance(v, list):
        for i, x in enumerate(v):
            yield from leaves(x, path + (i,))
    else:
        yield path, v


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--pictures", choices=["yes", "no", "any"], default="any")
    ap.add_argument("--note", action="append", default=[])
    a = ap.parse_args()
    d = a.dir
    page_file = os.path.join(d, "report.html")
    if not os.path.isfile(page_file):
        print(f"FAIL: {page_file} does not exist")
        return 1
    src = os.path.join(d, "report.json")
    if not os.path.isfile(src):
        src = os.path.join(d, "study.json")
    with open(src, encoding="utf-8") as f:
        report = json.load(f)
    raw = open(page_file, "rb").read()
    text = raw.decode("utf-8")

    # ---- valid HTML5 ----
    parser = html5lib.HTMLParser(strict=True, namespaceHTMLElements=False)
    try:
        doc = parser.parse(raw)
    except html5lib.html5parser.ParseError as e:
        fail(f"html5lib (strict): {e}; errors: {parser.errors[:5]}")
        doc = html5lib.parse(raw, namespaceHTMLElements=False)
    if not text.startswith("<!DOCTYPE html>"):
        fail("no <!DOCTYPE html> first")
    if shutil.which("tidy"):
        t = subprocess.run(["tidy", "-q", "-e", page_file], capture_output=True, text=True)
        if t.returncode != 0:
            fail("tidy: " + t.stderr.strip()[:2000])
    else:
        print("note: tidy is not installed; validated by html5lib only")

    # ---- self-contained ----
    for tag in ("script", "iframe", "object", "embed", "base"):
        if doc.findall(f".//{tag}"):
            fail(f"the page has a <{tag}>")
    for link in doc.findall(".//link"):
        fail(f"the page links {link.get('href')} (<link>)")
    ids = {e.get("id") for e in doc.iter() if e.get("id")}
    for e in doc.iter():
        for attr in ("href", "src"):
            u = e.get(attr)
            if u is None:
                continue
            if u.startswith("#"):
                if u[1:] not in ids:
                    fail(f"{attr}={u!r}: no element with that id")
                continue
            p = urllib.parse.urlsplit(u)
            if p.scheme or p.netloc or u.startswith("/") or ".." in u.split("/"):
                fail(f"{attr}={u!r} leaves the result directory")
                continue
            target = os.path.join(d, urllib.parse.unquote(p.path))
            if not os.path.isfile(target):
                fail(f"{attr}={u!r}: {target} does not exist")
            elif e.tag == "img":
                with open(target, "rb") as f:
                    if f.read(8) != b"\x89PNG\r\n\x1a\n":
                        fail(f"<img src={u!r}> is not a PNG file")
    shown_imgs = {urllib.parse.unquote(i.get("src")) for i in doc.findall(".//img")}
    on_disk = set()
    if os.path.isdir(os.path.join(d, "images")):
        on_disk = {"images/" + n for n in os.listdir(os.path.join(d, "images")) if n.endswith(".png")}
    if a.pictures == "yes":
        if not on_disk:
            fail("--pictures yes, but DIR/images holds no PNG")
        for m in sorted(on_disk - shown_imgs):
            fail(f"{m} is in the folder but not on the page")
    if a.pictures == "no" and shown_imgs:
        fail(f"--pictures no, but the page shows {sorted(shown_imgs)}")

    # ---- the same facts as the JSON ----
    values = []
    for e in doc.iter():
        v = e.get("data-value")
        if v is not None:
            try:
                values.append(float(json.loads(v)))
            except (ValueError, TypeError):
                fail(f"data-value={v!r} is not a JSON number")
    value_set = set(values)
    page_text = " ".join(" ".join(doc.itertext()).split())
    attr_text = " ".join(str(x) for e in doc.iter() for x in e.attrib.values())
    for path, v in leaves(report):
        where = ".".join(str(p) for p in path)
        if isinstance(v, bool) or v is None:
            continue
        if isinstance(v, (int, float)):
            if not (isinstance(v, float) and math.isnan(v)) and float(v) not in value_set:
                fail(f"{where} = {v} is not on the page")
        elif isinstance(v, str):
            s = " ".join(v.split())
            if s and s not in page_text and s not in attr_text:
                fail(f"{where} = {v[:80]!r} is not on the page")

    sections = {e.get("id"): e for e in doc.iter("section")}

    def shown(value, formatted, what, section=None):
        """An element (in <section id=section>, if given) whose data-value is `value` reads `formatted`."""
        scope = doc
        if section is not None:
            if section not in sections:
                fail(f"{what}: the page has no section {section!r}")
                return
            scope = sections[section]
        for e in scope.iter():
            dv = e.get("data-value")
            if dv is not None and float(json.loads(dv)) == float(value):
                t = " ".join("".join(e.itertext()).split())
                if t == formatted:
                    return
        fail(f"{what}: no element shows {value} as {formatted!r}")

    def um(mm, decimals=2):
        return f"{mm * 1e3:.{decimals}f} µm".replace("-", "−")

    cmd = report.get("command")
    if cmd == "run":
        for k, m in enumerate(report.get("marks", [])):
            shown(m["depth_mm"], um(m["depth_mm"]), f"mark {k + 1}'s depth", "marks")
        if report.get("marks"):
            shown(report["marks"][0]["depth_mm"], um(report["marks"][0]["depth_mm"]), "deepest mark", "summary")
        if "interpolation" in report:
            shown(report["interpolation"]["cycle_time_s"], f"{report['interpolation']['cycle_time_s']:.2f} s", "cycle time",
                  "summary")
        if "contour_error" in report:
            c = report["contour_error"]["cutting_moves"]["max_abs_mm"]
            shown(c, um(c), "contour error max", "summary")
    elif cmd == "compare":
        for k, m in enumerate(report["marks"]["list"]):
            shown(m["depth_mm"], um(m["depth_mm"]), f"mark {k + 1}'s depth", "marks")
        sa = report["areal"]["measured"]["Sa_mm"]
        shown(sa, um(sa, 3), "Sa measured", "areal")
    elif cmd == "oga":
        t = report["mse_table"]
        shown(t["change_percent"], f"{t['change_percent']:.1f} %".replace("-", "−"), "MSE change")
    elif cmd == "plan-feed":
        for run in ("no_plan", "plan"):
            ct = report["runs"][run]["cycle_time_s"]
            shown(ct, f"{ct:.2f} s", f"{run} cycle time")
    elif cmd == "compensate":
        e = report["contour_error"]["compensated_program_on_machine"]
        for when in ("before", "after"):
            shown(e[when]["max_mm"], um(e[when]["max_mm"]), f"contour error max {when}")
    elif cmd == "study":
        for v in report["variations"]:
            f = v.get("figures", {})
            if "mark_depth_mm" in f:
                shown(f["mark_depth_mm"], um(f["mark_depth_mm"]), f"variation {v['variation']}'s deepest mark", "results")
            run_page = v["dir"] + "/report.html"
            if os.path.isfile(os.path.join(d, run_page)):
                if not any(urllib.parse.unquote(x.get("href", "")) == run_page for x in doc.findall(".//a")):
                    fail(f"no link to {run_page}")
    for n in a.note:
        if " ".join(n.split()) not in page_text:
            fail(f"the page does not say {n!r}")

    if failures:
        print(f"FAIL {page_file}:")
        for f in failures:
            print("  " + f)
        return 1
    print(f"ok {page_file}: {len(raw)} bytes, {len(values)} figures, {len(shown_imgs)} pictures")
    return 0


if __name__ == "__main__":
    sys.exit(main())
