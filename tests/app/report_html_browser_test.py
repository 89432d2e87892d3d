#!/usr/bin/env python3
"""report.html in a real browser: headless Chromium driven by chromedriver (Debian's chromium, chromium-driver and
python3-selenium; scripts/install-deps.sh --test installs them).

  report_html_browser_test.py --vmsim build/app/vmsim --source . [--keep DIR]

Runs `vmsim run` on the plane-cylinder fast pass (the demo's job), `vmsim measure` + `vmsim compare` on its surface,
and a two-variation `vmsim study`, then opens each result's report.html from the file system, as a person opening it
from a file manager would, and checks:
- no message in the browser's console (a picture that fails to load is logged there as a SEVERE network error), and
  every <img> loaded (complete, naturalWidth > 0);
- a screenshot of the whole page is not blank, and the part picture is on it: the screenshot's pixels where the
  page shows images/part.png match that PNG scaled to the shown size (mean absolute difference), much better than
  they match the other pictures of the run (so the comparison can tell pictures apart);
- at phone width (390 px) the page does not scroll sideways (wide tables scroll in their own box) and no picture is
  wider than the window;
- printed (the browser's print to PDF) it gives a PDF of several pages, with the print style sheet in force (the
  section links hidden);
- the study's page links to each variation's page, and following the link opens it.
Exit 0: passed; 1: failed; 77: skipped (chromium, chromedriver, selenium or PIL missing), with the reason.
"""
import argparse
import base64
import io
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMEDRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"


def skip(why):
    print(f"SKIPPED: {why}")
    sys.exit(77)


if not os.path.exists(CHROMIUM):
    skip("chromium is not installed (Debian: chromium; scripts/install-deps.sh --test)")
if not os.path.exists(CHROMEDRIVER):
    skip("chromedriver is not installed (Debian: chromium-driver; scripts/install-deps.sh --test)")
try:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
except ImportError:
    skip("selenium is not installed (Debian: python3-selenium; scripts/install-deps.sh --test)")
try:
    from PIL import Image, ImageChops, ImageStat
except ImportError:
    skip("PIL is not installed (Debian: python3-pil; scripts/install-deps.sh --test)")

failures = []


def check(cond, msg):
    if not cond:
        failures.append(msg)
        print("FAIL: " + msg)
    return cond


def vmsim(exe, *args):
    t0 = time.time()
    r = subprocess.run([exe, *args], capture_output=True, text=True)
    print(f"$ vmsim {' '.join(args)}  ({time.time() - t0:.1f} s, exit {r.returncode})")
    if r.returncode != 0:
        print(r.stdout[-2000:], r.stderr[-2000:])
        sys.exit(1)
    return r


def browser(user_dir):
    o = webdriver.ChromeOptions()
    # The flags that work on a headless server as root: no sandbox (root), no GPU, and nothing that reaches out to the
    # network by itself (the page itself needs none).
    for a in ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
              "--disable-background-networking", "--disable-component-update", "--disable-sync",
              "--hide-scrollbars", "--force-device-scale-factor=1", "--user-data-dir=" + user_dir]:
        o.add_argument(a)
    o.binary_location = CHROMIUM
    o.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=o)


def open_page(d, page):
    d.get("file://" + os.path.abspath(page))
    # Local pictures load with the page, but wait for every one to be done loading, whatever its outcome.
    for _ in range(100):
        if d.execute_script("return document.readyState === 'complete' && "
                            "Array.from(document.images).every(i => i.complete)"):
            break
        time.sleep(0.1)


def console_and_images(d, page):
    logs = d.get_log("browser")
    check(not logs, f"{page}: console messages: {logs}")
    imgs = d.execute_script("return Array.from(document.images).map(i => [i.getAttribute('src'), i.complete, i.naturalWidth])")
    for src, complete, w in imgs:
        check(complete and w > 0, f"{page}: picture {src} did not load (complete {complete}, naturalWidth {w})")
    return imgs


def full_screenshot(d, width):
    d.set_window_size(width, 800)
    h = d.execute_script("return document.documentElement.scrollHeight")
    d.set_window_size(width, min(h, 16000))
    time.sleep(0.2)
    return Image.open(io.BytesIO(d.get_screenshot_as_png())).convert("RGB")


def mean_abs_diff(a, b):
    return sum(ImageStat.Stat(ImageChops.difference(a, b)).mean) / 3


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--vmsim", required=True)
    ap.add_argument("--source", required=True)
    ap.add_argument("--keep", help="a directory to keep the results and screenshots in")
    a = ap.parse_args()
    work = a.keep or tempfile.mkdtemp(prefix="vmsim_html_")
    os.makedirs(work, exist_ok=True)
    run_dir, meas_dir, cmp_dir, study_dir = (os.path.join(work, n) for n in ("run", "meas", "cmp", "study"))
    job = os.path.join(os.path.abspath(a.source), "parts", "plane_cylinder", "job_fast.toml")
    vmsim(a.vmsim, "run", job, "--quiet", "--image-size", "800x600", "--out", run_dir)
    vmsim(a.vmsim, "measure", os.path.join(run_dir, "surface.x3p"), "--reference", os.path.join(run_dir, "reference.x3p"),
          "--step", "50um", "--out", meas_dir)
    vmsim(a.vmsim, "compare", "-m", os.path.join(meas_dir, "scan.x3p"), "-p", os.path.join(run_dir, "reference.x3p"),
          "--out", cmp_dir)
    study_file = os.path.join(work, "study.toml")
    with open(study_file, "w") as f:
        f.write(f'[study]\nname = "kv"\njob = {json.dumps(job)}\n\n[common]\nremoval.spacing_mm = 0.25\n\n'
                '[grid]\nmachine.axes.X.drive.kv_1000_per_min = [3.0, 6.0]\n')
    vmsim(a.vmsim, "study", study_file, "--quiet", "--out", study_dir)

    user_dir = tempfile.mkdtemp(prefix="vmsim_chromium_")
    d = browser(user_dir)
    try:
        # ---- the run's page, desktop width ----
        page = os.path.join(run_dir, "report.html")
        open_page(d, page)
        imgs = console_and_images(d, page)
        check(len(imgs) == 12, f"{page}: {len(imgs)} pictures shown, the run drew 12")
        shot = full_screenshot(d, 1280)
        shot.save(os.path.join(work, "run_1280.png"))
        colours = len(set(shot.resize((shot.width // 4, shot.height // 4)).getdata()))
        stat = ImageStat.Stat(shot.convert("L"))
        print(f"screenshot {shot.width} x {shot.height}: {colours} colours, grey level sd {stat.stddev[0]:.1f}")
        check(colours > 500 and stat.stddev[0] > 20, "the screenshot is (nearly) blank")
        # Where the page shows the part picture, in screenshot pixels.
        el = d.find_element(By.CSS_SELECTOR, 'img[src="images/part.png"]')
        r = d.execute_script("const r = arguments[0].getBoundingClientRect();"
                             "return [r.left + window.scrollX, r.top + window.scrollY, r.width, r.height, window.devicePixelRatio]", el)
        x, y, w, h, dpr = (v * r[4] if i < 4 else v for i, v in enumerate(r))
        box = tuple(round(v) for v in (x + 1, y + 1, x + w - 1, y + h - 1))  # inside its 1 px border
        check(box[2] - box[0] > 200 and box[3] - box[1] > 150, f"the part picture is shown at {box}: too small")
        region = shot.crop(box)
        size = region.size

        def scaled(name):
            return Image.open(os.path.join(run_dir, "images", name)).convert("RGB").resize(size, Image.BILINEAR)

        part = mean_abs_diff(region, scaled("part.png"))
        others = {n: mean_abs_diff(region, scaled(n)) for n in ("part_mark.png", "deviation_3d.png", "deviation.png", "feed.png")}
        print(f"part picture at {box}: mean |difference| to part.png {part:.2f}, to the others "
              + ", ".join(f"{n} {v:.1f}" for n, v in others.items()))
        check(part < 6.0, f"the screenshot does not show part.png where the page places it (difference {part:.2f})")
        check(all(v > 3 * part for v in others.values()), "the comparison cannot tell part.png from the other pictures")

        # ---- print ----
        d.execute_cdp_cmd("Emulation.setEmulatedMedia", {"media": "print"})
        nav = d.execute_script("return getComputedStyle(document.querySelector('nav')).display")
        check(nav == "none", f"print style: the section links are shown ({nav})")
        d.execute_cdp_cmd("Emulation.setEmulatedMedia", {"media": ""})
        pdf = base64.b64decode(d.print_page())
        with open(os.path.join(work, "run.pdf"), "wb") as f:
            f.write(pdf)
        pages = len(re.findall(rb"/Type\s*/Page[^s]", pdf))
        print(f"printed: {len(pdf)} bytes, {pages} pages")
        check(pdf.startswith(b"%PDF") and pages >= 3, f"print to PDF: {pages} pages")

        # ---- phone width ----
        d.set_window_size(390, 844)
        time.sleep(0.2)
        sw, iw = d.execute_script("return [document.documentElement.scrollWidth, window.innerWidth]")
        check(sw <= iw, f"at 390 px the page scrolls sideways: {sw} px wide in a {iw} px window")
        wide = d.execute_script("return Array.from(document.images).filter(i => i.getBoundingClientRect().right > "
                                "window.innerWidth + 1).map(i => i.getAttribute('src'))")
        check(not wide, f"at 390 px these pictures are wider than the window: {wide}")
        full_screenshot(d, 390).save(os.path.join(work, "run_390.png"))

        # ---- compare's page ----
        page = os.path.join(cmp_dir, "report.html")
        d.set_window_size(1280, 900)
        open_page(d, page)
        imgs = console_and_images(d, page)
        check(any(s == "images/deviation_map.png" for s, _, _ in imgs), f"{page}: no deviation map")
        full_screenshot(d, 1280).save(os.path.join(work, "compare_1280.png"))

        # ---- the study's page and a link to a variation's ----
        page = os.path.join(study_dir, "report.html")
        open_page(d, page)
        console_and_images(d, page)
        links = d.execute_script("return Array.from(document.querySelectorAll('#results a')).map(a => a.getAttribute('href'))")
        check(links == ["variations/001/report.html", "variations/002/report.html"], f"{page}: links {links}")
        if links:
            d.find_element(By.CSS_SELECTOR, '#results a[href="variations/002/report.html"]').click()
            time.sleep(0.5)
            check(d.current_url.endswith("/variations/002/report.html"), f"the link opened {d.current_url}")
            check("vmsim run" in d.title, f"the variation's page is titled {d.title!r}")
            console_and_images(d, d.current_url)
    finally:
        d.quit()
        shutil.rmtree(user_dir, ignore_errors=True)
    if not a.keep:
        shutil.rmtree(work, ignore_errors=True)
    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("report.html in Chromium: every check passed" + (f" (files in {work})" if a.keep else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
