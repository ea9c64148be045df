"""Screenshots of the built docs at 1200 px and the pages whose formulas or code overflow.

Builds nothing itself: run ``sphinx-build -W -q -b html docs docs/_build/html`` first. Each page
is copied (with the rest of the built site, so that its links and the offline MathJax still
resolve) into a temporary folder with a small script appended; headless Chromium loads it in a
1200 px wide window, the script waits for MathJax to typeset and writes into the page what
overflows, and ``--dump-dom`` returns it. Checked:

- display formulas (``mjx-container[display]``) wider than their container (MathJax then
  shows a horizontal scroll bar or cuts them) or whose right edge passes the text column;
- inline formulas whose right edge passes the text column;
- code blocks (``pre``) and tables wider than the text column.

A screenshot of each page (its top, 1200 x ``--height`` px) goes to ``--out``, taken with the
project's bounded launcher (:func:`ucontrol.viz.browser_screenshot.screenshot`).

Usage::

    python experiments/docs_screenshots.py [--html docs/_build/html] [--out runs/docs_screenshots]
        [--pages moreau_jean controller] [--no-screenshots]

Exit status 1 when a page overflows.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from ucontrol.viz.browser_screenshot import CHROMIUM_FLAGS, TIMEOUT, find_chromium, screenshot

#: Width of the browser window in [px] (issue 18: no scroll bar at 1200 px).
WIDTH = 1200
#: Virtual time given to MathJax to typeset a page, in [ms].
TYPESET_MS = 8000
#: Tolerance of the width comparisons in [px] (sub-pixel rounding).
SLACK = 1.0

_CHECK = """
<script>
(function () {
  function report() {
    var column = document.querySelector("div.body") || document.body;
    var right = column.getBoundingClientRect().right + %(slack)s;
    var out = [];
    function text(el) { return (el.textContent || "").replace(/\\s+/g, " ").slice(0, 80); }
    document.querySelectorAll("mjx-container").forEach(function (el) {
      var box = el.getBoundingClientRect();
      var display = el.getAttribute("display") === "true";
      var inner = el.firstElementChild ? el.firstElementChild.getBoundingClientRect() : box;
      if (display && (el.scrollWidth > el.clientWidth + %(slack)s || inner.right > right)) {
        out.push({kind: "display formula", width: inner.width, text: text(el)});
      } else if (!display && box.right > right) {
        out.push({kind: "inline formula", width: box.width, text: text(el)});
      }
    });
    document.querySelectorAll("pre").forEach(function (el) {
      if (el.scrollWidth > el.clientWidth + %(slack)s || el.getBoundingClientRect().right > right) {
        out.push({kind: "code block", width: el.scrollWidth, text: text(el)});
      }
    });
    document.querySelectorAll("table").forEach(function (el) {
      if (el.getBoundingClientRect().right > right) {
        out.push({kind: "table", width: el.getBoundingClientRect().width, text: text(el)});
      }
    });
    var n = document.querySelectorAll("mjx-container").length;
    var node = document.createElement("pre");
    node.id = "overflow-report";
    node.textContent = JSON.stringify({formulas: n, column: right, overflows: out});
    document.body.appendChild(node);
  }
  window.addEventListener("load", function () {
    if (window.MathJax && MathJax.startup && MathJax.startup.promise) {
      MathJax.startup.promise.then(report);
    } else {
      report();
    }
  });
})();
</script>
"""


def check_page(site: Path, page: Path, width: int = WIDTH) -> dict[str, object]:
    """Overflows of one built page (a path relative to ``site``), loaded ``width`` px wide.

    Args:
        site: A writable copy of the built site.
        page: The page, relative to ``site``.
        width: Width of the window in [px].

    Returns:
        ``formulas`` (count), ``column`` (right edge of the text in [px]) and ``overflows``
        (kind, width in [px], start of the text), or ``error`` when no report came back.
    """
    executable = find_chromium()
    if executable is None:
        return {"error": "chromium is not installed"}
    source = site / page
    probe = source.with_name(f"_overflow_{source.name}")
    html = source.read_text()
    script = _CHECK % {"slack": SLACK}
    probe.write_text(html.replace("</body>", script + "</body>") if "</body>" in html else html)
    with tempfile.TemporaryDirectory() as profile:
        command = [
            executable,
            *CHROMIUM_FLAGS,
            f"--user-data-dir={profile}",
            f"--window-size={width},900",
            "--proxy-server=127.0.0.1:9",  # offline: the page must need no network
            "--proxy-bypass-list=<-loopback>",
            f"--virtual-time-budget={TYPESET_MS}",
            "--dump-dom",
            probe.as_uri(),
        ]
        try:
            dom = subprocess.run(command, capture_output=True, text=True, timeout=TIMEOUT).stdout
        except subprocess.TimeoutExpired as error:
            dom = error.stdout.decode() if isinstance(error.stdout, bytes) else ""
    probe.unlink(missing_ok=True)
    match = re.search(r'<pre id="overflow-report">(.*?)</pre>', dom, re.S)
    if match is None:
        return {"error": "no report (the page did not finish loading)"}
    text = match.group(1).replace("&quot;", '"').replace("&lt;", "<").replace("&gt;", ">")
    return json.loads(text.replace("&amp;", "&"))


def main(argv: list[str] | None = None) -> int:
    """Check every page (or the ones named) and print one line per page."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--html", type=Path, default=Path("docs/_build/html"), help="built site")
    parser.add_argument("--out", type=Path, default=Path("runs/docs_screenshots"))
    parser.add_argument("--pages", nargs="*", help="page names (default: every page)")
    parser.add_argument("--height", type=int, default=1600, help="screenshot height in [px]")
    parser.add_argument("--no-screenshots", action="store_true", help="overflow check only")
    parser.add_argument("--width", type=int, default=WIDTH, help="window width in [px]")
    args = parser.parse_args(argv)
    if not (args.html / "index.html").is_file():
        parser.error(f"no built site in {args.html}: run sphinx-build -b html docs {args.html}")
    pages = sorted(  # the pages written by hand (not the API reference nor the indices)
        path.relative_to(args.html)
        for path in args.html.rglob("*.html")
        if path.stem not in {"genindex", "search", "py-modindex"}
        and not any(part.startswith("_") for part in path.relative_to(args.html).parts)
    )
    if args.pages:
        pages = [page for page in pages if page.stem in set(args.pages)]
    args.out.mkdir(parents=True, exist_ok=True)
    failing = 0
    with tempfile.TemporaryDirectory() as folder:
        site = Path(folder) / "html"
        shutil.copytree(args.html, site, ignore=shutil.ignore_patterns("_sources", ".doctrees"))
        for page in pages:
            result = check_page(site, page, args.width)
            if not args.no_screenshots:
                screenshot(
                    (site / page).as_uri(),
                    args.out / f"{page.stem}.png",
                    width=args.width,
                    height=args.height,
                    virtual_time_ms=TYPESET_MS,
                    offline=True,
                )
            if "error" in result:
                failing += 1
                print(f"{page}: {result['error']}")
                continue
            overflows = result["overflows"]
            assert isinstance(overflows, list)
            failing += bool(overflows)
            status = "OK" if not overflows else f"{len(overflows)} overflow(s)"
            column = float(result["column"])  # type: ignore[arg-type]
            print(
                f"{page}: {result['formulas']} formulas, text column to {column:.0f} px, {status}"
            )
            for item in overflows:
                print(f"    {item['kind']} {item['width']:.0f} px: {item['text']}")
    print(f"{len(pages) - failing} of {len(pages)} pages without overflow at {args.width} px")
    return 1 if failing else 0


if __name__ == "__main__":
    sys.exit(main())
