#!/usr/bin/env python3
"""Draws an exported .glb with three.js in headless Chromium (software GL) and saves a PNG.

    python3 tools/threejs-check/browser/run.py MODEL.glb OUT.png [--size 800x600] [--seconds 5]
        [--no-lod]

Serves index.html, the MSFT_lod plugin (tools/threejs-check/msft-lod.mjs; --no-lod leaves it
out, so three.js draws the full levels only, as its GLTFLoader alone does), three.js
(tools/threejs-check/node_modules/three) and the model from
127.0.0.1 on a free port, opens the page in `chromium --headless` and waits for the page to
post its picture and figures (frames of requestAnimationFrame over at least --seconds and 3
frames, at most 20 x --seconds; triangles per frame from three.js's renderer.info); prints the
figures as JSON (OUT.png's stem + .json is written too). Needs Debian's `chromium`.
"""
import argparse
import base64
import http.server
import json
import pathlib
import shutil
import subprocess
import sys
import tempfile
import threading

HERE = pathlib.Path(__file__).resolve().parent


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("model")
    ap.add_argument("out")
    ap.add_argument("--size", default="800x600")
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--no-lod", action="store_true", help="draw without the MSFT_lod plugin")
    ap.add_argument("--log", help="write Chromium's log (the page's console too) here")
    args = ap.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    three = HERE.parent / "node_modules" / "three"
    if not (three / "package.json").exists():
        sys.exit("three.js is not installed: run scripts/install-deps.sh")
    result = {}
    done = threading.Event()
    with tempfile.TemporaryDirectory() as tmp:
        root = pathlib.Path(tmp)
        shutil.copy(HERE / "index.html", root / "index.html")
        shutil.copy(HERE.parent / "msft-lod.mjs", root / "msft-lod.mjs")
        (root / "three").symlink_to(three)
        (root / "model.glb").symlink_to(pathlib.Path(args.model).resolve())

        class Handler(http.server.SimpleHTTPRequestHandler):
            def __init__(self, *a, **k):
                super().__init__(*a, directory=str(root), **k)

            def log_message(self, *a):
                pass

            def do_POST(self):
                body = self.rfile.read(int(self.headers["Content-Length"]))
                result.update(json.loads(body))
                self.send_response(204)
                self.end_headers()
                done.set()

        Handler.extensions_map[".mjs"] = "text/javascript"
        Handler.extensions_map[".js"] = "text/javascript"
        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        threading.Thread(target=server.serve_forever, daemon=True).start()
        port = server.server_address[1]
        url = f"http://127.0.0.1:{port}/index.html?width={width}&height={height}&seconds={args.seconds}&lod={0 if args.no_lod else 1}"
        profile = root / "profile"
        browser = subprocess.Popen(
            [
                "chromium", "--headless=new", "--no-sandbox", "--disable-gpu-sandbox",
                "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                "--ignore-gpu-blocklist", "--disable-background-timer-throttling",
                "--disable-renderer-backgrounding", f"--user-data-dir={profile}",
                f"--window-size={width},{height}", "--enable-logging=stderr", url,
            ],
            stdout=subprocess.DEVNULL,
            stderr=open(args.log, "wb") if args.log else subprocess.DEVNULL,
        )
        try:
            if not done.wait(args.timeout):
                sys.exit(f"no result from the page within {args.timeout} s")
        finally:
            browser.terminate()
            try:
                browser.wait(10)
            except subprocess.TimeoutExpired:
                browser.kill()
            server.shutdown()
    if not result.get("ok"):
        sys.exit(f"the page failed: {result.get('error')}")
    png = result.pop("png")
    out = pathlib.Path(args.out)
    out.write_bytes(base64.b64decode(png.split(",", 1)[1]))
    out.with_suffix(".json").write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
