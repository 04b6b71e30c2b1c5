"""`refspatial-gen audit serve D`: the review page on localhost, appending each verdict to verdicts.jsonl.

Why a server: a page opened from disk cannot write files; served, every key press is saved at once, so
an interrupted review loses nothing. Bound to 127.0.0.1 only; serves files of the audit folder only.
"""

from __future__ import annotations

import json
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

from refspatial_gen.audit.verdicts import Verdict, append_verdict

MAX_BODY = 64 * 1024


class _Handler(SimpleHTTPRequestHandler):
    audit_dir: Path

    def do_POST(self) -> None:  # noqa: N802 (http.server's naming)
        if self.path.rstrip("/").split("/")[-1] != "verdict":
            self.send_error(404, "POST only to /verdict")
            return
        length = int(self.headers.get("Content-Length") or 0)
        if not 0 < length <= MAX_BODY:
            self.send_error(413 if length else 411, "verdict body missing or too large")
            return
        try:
            d = json.loads(self.rfile.read(length))
            append_verdict(self.audit_dir, Verdict(str(d["item_id"]), str(d["verdict"]), str(d.get("note", ""))))
        except (ValueError, KeyError, TypeError) as e:
            self.send_error(400, str(e)[:200])
            return
        self.send_response(204)
        self.end_headers()

    def end_headers(self) -> None:
        self.send_header("Cache-Control", "no-store")
        super().end_headers()

    def log_message(self, format: str, *args: object) -> None:  # quiet: one line per verdict is noise
        return


def make_server(audit_dir: Path, port: int = 0) -> ThreadingHTTPServer:
    """A server for `audit_dir` on 127.0.0.1:`port` (0 = any free port); call serve_forever()."""
    audit_dir = Path(audit_dir).resolve()
    handler = type("AuditHandler", (_Handler,), {"audit_dir": audit_dir})
    return ThreadingHTTPServer(("127.0.0.1", port), partial(handler, directory=str(audit_dir)))
