"""A scripted OpenAI-compatible chat server on 127.0.0.1 for the rewrite tests.

Each request's behaviour is fixed by a hash of its last user message, so outcomes do not depend on
timing: some requests misbehave once (slow past the client's timeout, HTTP 500, a dropped connection,
an unreadable envelope) and then answer well; some always fail; some answer with text that is not JSON,
or with a rewrite that breaks a rule (another object named, the answer leaked, the relation flipped).
`json_schema` response formats are refused (as llama-cpp-python's server does), so the client must fall
back. The server records what it expects each pair's outcome to be, for the test to compare.
"""

from __future__ import annotations

import hashlib
import json
import re
import socket
import threading
import time
from collections import Counter
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

# behaviour -> the stage's expected outcome for that pair
BEHAVIOURS = {
    "good": "accepted", "slow_once": "accepted", "http500_once": "accepted", "drop_once": "accepted",
    "envelope_once": "accepted", "always_503": "server_error", "not_json": "bad_json", "extra": "extra_object",
    "leak": "leaked_answer", "flip": "relation_changed",
}
ORDER = sorted(BEHAVIOURS)
PROMPTS = """\
system: 'Rewrite the question. Reply with JSON {"question": "..."}.'
user: |-
  Q: {question}
  A: {answer}
ask_answer: false
"""


def reworded(q: str) -> str:
    return "Looking at the photo: " + q


class State:
    def __init__(self, slow_s: float, force: str | None = None) -> None:
        self.lock = threading.Lock()
        self.slow_s, self.force = slow_s, force
        self.requests = 0
        self.attempts: Counter = Counter()
        self.expected: dict[str, str] = {}  # user message -> expected outcome
        self.formats: Counter = Counter()

    def behaviour(self, user: str) -> str:
        if self.force:
            return self.force
        return ORDER[int(hashlib.sha256(user.encode()).hexdigest(), 16) % len(ORDER)]


class _Handler(BaseHTTPRequestHandler):
    server: "ScriptedServer"

    def log_message(self, *a) -> None:  # quiet
        pass

    def _send(self, code: int, payload: bytes, ctype: str = "application/json") -> None:
        try:
            self.send_response(code)
            self.send_header("Content-Type", ctype)
            self.send_header("Content-Length", str(len(payload)))
            self.end_headers()
            self.wfile.write(payload)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the client gave up (timeout)

    def _reply(self, text: str) -> None:
        env = {"id": "x", "object": "chat.completion", "model": "scripted",
               "choices": [{"index": 0, "finish_reason": "stop", "message": {"role": "assistant", "content": text}}]}
        self._send(200, json.dumps(env).encode())

    def do_POST(self) -> None:  # noqa: N802 - http.server's name
        st = self.server.state
        body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
        rf = (body.get("response_format") or {}).get("type", "none")
        with st.lock:
            st.requests += 1
            st.formats[rf] += 1
        if rf == "json_schema":
            self._send(500, b'{"error": {"message": "body.response_format.type: Input should be text or json_object"}}')
            return
        user = body["messages"][-1]["content"]
        q = re.search(r"^Q: (.*)$", user, re.M).group(1)
        b = st.behaviour(user)
        with st.lock:
            st.attempts[user] += 1
            n = st.attempts[user]
            st.expected[user] = BEHAVIOURS[b]
        if b == "slow_once" and n == 1:
            time.sleep(st.slow_s)
        elif b == "http500_once" and n == 1:
            return self._send(500, b'{"error": "overloaded"}')
        elif b == "drop_once" and n == 1:
            self.close_connection = True
            self.request.shutdown(socket.SHUT_RDWR)
            return None
        elif b == "envelope_once" and n == 1:
            return self._send(200, b"<html>upstream proxy error</html>", "text/html")
        elif b == "always_503":
            return self._send(503, b'{"error": "unavailable"}')
        if b == "not_json":
            return self._reply("Sure! Here is a nicer question: " + q)
        new = reworded(q)
        if b == "extra":
            new = new.rstrip("?.") + " next to the lamp?"
        elif b == "leak":
            new = new.rstrip("?.") + ", and is the answer yes?"
        elif b == "flip":
            new = "Not quite, but " + new
        return self._reply(json.dumps({"question": new}))


class ScriptedServer(ThreadingHTTPServer):
    daemon_threads = True

    def __init__(self, slow_s: float = 1.0, force: str | None = None) -> None:
        super().__init__(("127.0.0.1", 0), _Handler)
        self.state = State(slow_s, force)
        self._thread = threading.Thread(target=self.serve_forever, daemon=True)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.server_address[1]}/v1"

    def __enter__(self) -> "ScriptedServer":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.shutdown()
        self.server_close()
