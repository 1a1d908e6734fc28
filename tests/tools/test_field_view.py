#!/usr/bin/env python3
"""The field viewer in a real browser: render veach-ajar with guiding and --save-field,
write the page with `theia field view`, load it in headless Chromium (Debian's chromium,
driven over the DevTools protocol with python3-websocket) and check that it runs without
JavaScript errors, draws as many leaves as the field has, and that clicking a leaf shows
its distribution: the page's map, screenshotted, against the PNG `theia field image`
writes for the same leaf.

usage: test_field_view.py THEIA SCENES_DIR [--docs DIR] [--field sdtree|vmm]
--docs DIR writes the README's screenshots there; --field vmm saves the mixture field (the page then
evaluates each leaf's lobes, re-pointed to the leaf's centre, as `theia field image` does).  Exit 77 (CTest: skipped), saying why,
only when Chromium is missing or cannot start.
"""
import argparse
import base64
import io
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

SKIP = 77


def skip(why):
    print(f"SKIP: {why}")
    sys.exit(SKIP)


def fail(why):
    print(f"FAIL: {why}")
    sys.exit(1)


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        fail(f"{' '.join(map(str, cmd))} exited {r.returncode}:\n{r.stdout}{r.stderr}")
    return r.stdout


class Browser:
    """Headless Chromium and one page, over the DevTools protocol."""

    def __init__(self):
        chromium = shutil.which("chromium") or shutil.which("chromium-browser")
        if not chromium:
            skip("no chromium on PATH (Debian: apt-get install chromium)")
        try:
            import websocket  # python3-websocket
        except ImportError:
            fail("no python3-websocket (tools/install-deps.sh installs it)")
        # Its own profile folder, outside the test's: Chromium's helper processes can still
        # write there for a moment after the browser has exited (close() removes it).
        self.profile = profile = tempfile.mkdtemp(prefix="theia_field_view_chromium_")
        self.proc = subprocess.Popen(
            [chromium, "--headless=new", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
             "--enable-unsafe-swiftshader", "--force-device-scale-factor=1", "--window-size=1500,820",
             "--hide-scrollbars", "--allow-file-access-from-files", "--remote-debugging-port=0",
             f"--user-data-dir={profile}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        port_file = pathlib.Path(profile) / "DevToolsActivePort"
        deadline = time.time() + 30
        while not port_file.exists() or not port_file.read_text().strip():
            if self.proc.poll() is not None:
                skip(f"chromium could not start: {self.proc.stderr.read().decode(errors='replace')[-800:]}")
            if time.time() > deadline:
                self.close()
                skip("chromium did not open its DevTools port within 30 s")
            time.sleep(0.1)
        port = int(port_file.read_text().split()[0])
        import urllib.request
        # The port file can appear before the page is listed (or the server answers): ask until it is.
        page = None
        while page is None:
            try:
                targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list"))
                page = next((t for t in targets if t["type"] == "page"), None)
            except OSError:
                pass
            if page is None:
                if time.time() > deadline:
                    self.close()
                    fail("chromium listed no page within 30 s")
                time.sleep(0.1)
        self.ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=60, suppress_origin=True)
        self.next_id = 0
        self.events = []

    def call(self, method, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    fail(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self.events.append(msg)

    def eval(self, expression):
        r = self.call("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            fail(f"{expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def errors(self):
        """JavaScript exceptions and console errors so far."""
        out = []
        for e in self.events:
            if e.get("method") == "Runtime.exceptionThrown":
                out.append(e["params"]["exceptionDetails"].get("exception", {}).get("description", str(e)))
            if e.get("method") == "Runtime.consoleAPICalled" and e["params"]["type"] == "error":
                out.append(" ".join(str(a.get("value", a.get("description"))) for a in e["params"]["args"]))
            if e.get("method") == "Log.entryAdded" and e["params"]["entry"]["level"] == "error":
                out.append(e["params"]["entry"]["text"])
        return out

    def screenshot(self, clip=None):
        params = {"format": "png"}
        if clip:
            params["clip"] = dict(clip, scale=1)
        return base64.b64decode(self.call("Page.captureScreenshot", **params)["data"])

    def click(self, x, y):
        for kind in ("mousePressed", "mouseReleased"):
            self.call("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left", clickCount=1)

    def close(self):
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        for _ in range(20):
            try:
                shutil.rmtree(self.profile)
                return
            except FileNotFoundError:
                return
            except OSError:
                time.sleep(0.25)
        shutil.rmtree(self.profile, ignore_errors=True)


def wait_for(browser, expression, seconds):
    deadline = time.time() + seconds
    while time.time() < deadline:
        if browser.eval(expression):
            return
        time.sleep(0.2)
    fail(f"timed out waiting for {expression}; errors: {browser.errors()}")


def compare(page_png, reference_png):
    """Mean and largest per-channel difference, and the share of pixels that differ at all."""
    from PIL import Image, ImageChops
    a = Image.open(io.BytesIO(page_png)).convert("RGB")
    b = Image.open(reference_png).convert("RGB")
    if a.size != b.size:
        fail(f"the page's map is {a.size}, field image wrote {b.size}")
    diff = ImageChops.difference(a, b)
    values = list(diff.getdata())
    total = sum(sum(v) for v in values)
    differing = sum(1 for v in values if any(v))
    return total / (3 * len(values)), max(max(v) for v in values), differing / len(values)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("theia")
    ap.add_argument("scenes")
    ap.add_argument("--docs")
    ap.add_argument("--field", default="sdtree", choices=["sdtree", "vmm"])
    args = ap.parse_args()
    start = time.time()
    with tempfile.TemporaryDirectory(prefix="theia_field_view_") as tmp:
        tmp = pathlib.Path(tmp)
        field = tmp / "ajar.field"
        run([args.theia, "render", f"{args.scenes}/veach-ajar/scene.pbrt", "--guiding", "--spp", "8", "-q",
             "--guiding-field", args.field, "--save-field", field, "--save-field-every-iteration",
             "-o", tmp / "ajar.exr"])
        run([args.theia, "field", "view", field, "-o", tmp / "page"])
        stats = json.loads(run([args.theia, "field", "stats", "--json", field]))
        browser = Browser()
        try:
            check_page(browser, args, tmp, field, stats)
        finally:
            browser.close()
    print(f"PASS in {time.time() - start:.1f} s")


def set_input(browser, element, value):
    browser.eval(f"(() => {{ const e = document.getElementById('{element}'); e.value = {value}; "
                 "e.dispatchEvent(new Event('input')); })()")


def check_timeline_and_slicing(browser, args, field, stats):
    """The first snapshot on the timeline draws its own leaves; a slicing plane keeps the leaves below it."""
    first = browser.eval("THEIA_FIELD.snapshots[0].iteration")
    first_stats = json.loads(run([args.theia, "field", "stats", "--json", "--iteration", str(first), field]))
    set_input(browser, "timeline", 0)
    drawn, count = browser.eval("theiaViewer.drawnLeaves"), browser.eval("theiaViewer.leafCount")
    print(f"timeline at iteration {first}: field {first_stats['leaves']}, page {count}, drawn {drawn}")
    if not (drawn == count == first_stats["leaves"]):
        fail(f"iteration {first}: drawn {drawn}, page's count {count}, field's {first_stats['leaves']}")
    set_input(browser, "timeline", browser.eval("THEIA_FIELD.snapshots.length - 1"))
    root = stats["root_bounds"]
    for axis in range(3):
        plane = root[axis] + 0.5 * (root[axis + 3] - root[axis])
        expected = sum(1 for b in stats["boxes"] if b[axis] <= plane)
        set_input(browser, f"slice{axis}", 500)
        drawn = browser.eval("theiaViewer.drawnLeaves")
        set_input(browser, f"slice{axis}", 1000)
        print(f"slice {'xyz'[axis]} at the middle: drawn {drawn}, leaves starting below it {expected}")
        if drawn != expected or expected == stats["leaves"]:
            fail(f"slicing {'xyz'[axis]}: drawn {drawn}, expected {expected} of {stats['leaves']}")
    if browser.eval("theiaViewer.drawnLeaves") != stats["leaves"]:
        fail("the slices back at the top do not draw every leaf")


def check_page(browser, args, tmp, field, stats):
    for domain in ("Runtime", "Log", "Page"):
        browser.call(f"{domain}.enable")
    browser.call("Page.navigate", url=(tmp / "page" / "index.html").as_uri())
    wait_for(browser, "window.theiaViewer && (theiaViewer.ready || theiaViewer.errors.length > 0)", 60)
    time.sleep(0.5)  # a few frames drawn
    errors = browser.errors() + browser.eval("theiaViewer.errors")
    if errors:
        fail(f"JavaScript errors: {errors}")
    drawn, count = browser.eval("theiaViewer.drawnLeaves"), browser.eval("theiaViewer.leafCount")
    print(f"leaves: field {stats['leaves']}, page {count}, drawn {drawn}")
    if not (drawn == count == stats["leaves"]):
        fail(f"drawn leaves {drawn}, page's count {count}, field's {stats['leaves']}")
    if args.docs:
        pathlib.Path(args.docs, "field-view.png").write_bytes(browser.screenshot())
    check_timeline_and_slicing(browser, args, field, stats)

    # Click the busiest leaves' centres until one is picked: a leaf in front may be the one hit.
    samples = stats["per_leaf"]["samples"]
    # Leaves that guide: a mixture field's fitted regions, an SD-tree's leaves with energy.
    energy = stats["per_leaf"].get("vmm_fitted", stats["per_leaf"]["has_energy"])
    order = sorted(range(len(samples)), key=lambda i: -samples[i])
    picked = -1
    for leaf in [i for i in order if energy[i] > 0][:40]:
        p = browser.eval(f"theiaViewer.leafScreenPosition({leaf})")
        if not p["inside"]:
            continue
        browser.click(p["x"], p["y"])
        picked = browser.eval("theiaViewer.selected")
        if picked >= 0:
            break
    if picked < 0:
        fail("no click on a leaf's centre selected a leaf")
    time.sleep(0.3)
    box = browser.eval(f"window.THEIA_FIELD.snapshots[window.THEIA_FIELD.snapshots.length - 1].leaves[{picked}].box")
    centre = [str((box[a] + box[a + 3]) / 2) for a in range(3)]
    reference = tmp / "leaf.png"
    run([args.theia, "field", "image", field, "--point", *centre, "--width", "256", "-o", reference])
    rect = browser.eval("theiaViewer.mapRect()")
    mean, largest, share = compare(browser.screenshot(rect), reference)
    print(f"leaf {picked}: page map against field image: mean difference {mean:.4f}, largest {largest}, "
          f"{100 * share:.2f}% of pixels differ")
    if mean > 0.5 or share > 0.01:
        fail("the page's distribution is not the one `theia field image` writes for the same leaf")
    errors = browser.errors() + browser.eval("theiaViewer.errors")
    if errors:
        fail(f"JavaScript errors after the click: {errors}")
    if args.docs:
        pathlib.Path(args.docs, "field-view-leaf.png").write_bytes(browser.screenshot())
        shutil.copy(reference, pathlib.Path(args.docs, "field-image.png"))


if __name__ == "__main__":
    main()
