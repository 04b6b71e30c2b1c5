"""A minimal client for any OpenAI-compatible `/v1/chat/completions` server, with timeouts and retries.

Why the standard library: the stage needs one POST with JSON in and out (vLLM, SGLang, llama.cpp's
server, `transformers serve` and hosted APIs all speak it), and it must control exactly what is retried:
connection failures, timeouts, dropped connections, 408/429/5xx and unreadable envelopes are retried with
exponential back-off; a 400/422 that names the requested JSON format makes the caller try a weaker format
(`FormatUnsupported`); anything else, or running out of attempts, is a `ServerError`. The model's own
output is returned as text: whether it is usable JSON is the caller's question (it is not retried, because
the same request gives the same output).
"""

from __future__ import annotations

import http.client
import json
import socket
import time
import urllib.error
import urllib.request
from collections.abc import Callable
from typing import Any


def reply_schema(ask_answer: bool) -> dict[str, Any]:
    """JSON schema of a reply: {"question"} or {"question", "answer"}."""
    props = {"question": {"type": "string"}, **({"answer": {"type": "string"}} if ask_answer else {})}
    return {"type": "object", "properties": props, "required": sorted(props), "additionalProperties": False}


FORMATS = ("json_schema", "json_object", "none")


class ServerError(Exception):
    """The server gave no usable reply after every attempt (reason: timeout, connection, http_NNN, envelope)."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason, self.detail = reason, detail


class FormatUnsupported(Exception):
    """The server rejected the requested response_format (the caller falls back to a weaker one)."""


def response_format(mode: str, schema: dict[str, Any]) -> dict[str, Any] | None:
    if mode == "json_schema":
        return {"type": "json_schema", "json_schema": {"name": "rewrite", "schema": schema, "strict": True}}
    if mode == "json_object":
        return {"type": "json_object", "schema": schema}  # `schema` is llama.cpp's extension; others ignore it
    return None


class ChatClient:
    """POSTs chat requests to `base_url` (".../v1"); thread-safe (no shared connection state)."""

    def __init__(
        self,
        base_url: str,
        *,
        api_key: str | None = None,
        timeout: float = 60.0,
        retries: int = 3,
        backoff: float = 0.5,
        backoff_max: float = 8.0,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.url = base_url.rstrip("/") + "/chat/completions"
        self.api_key, self.timeout, self.retries = api_key, timeout, retries
        self.backoff, self.backoff_max, self.sleep = backoff, backoff_max, sleep
        self.requests = 0  # HTTP requests sent (retries included); read by tests and the bench

    def complete(self, body: dict[str, Any], mode: str, schema: dict[str, Any] | None = None) -> str:
        """The assistant message text for `body` (model, messages, sampling parameters) in format `mode`."""
        payload = dict(body)
        rf = response_format(mode, schema or reply_schema(True))
        if rf is not None:
            payload["response_format"] = rf
        data = json.dumps(payload).encode()
        last = ServerError("no_attempt")
        for attempt in range(self.retries + 1):
            if attempt:
                self.sleep(min(self.backoff_max, self.backoff * 2 ** (attempt - 1)))
            try:
                return self._once(data, mode)
            except _Fatal:
                raise
            except ServerError as e:
                last = e
        raise last

    def _once(self, data: bytes, mode: str) -> str:
        headers = {"Content-Type": "application/json"}
        if self.api_key:
            headers["Authorization"] = f"Bearer {self.api_key}"
        req = urllib.request.Request(self.url, data=data, headers=headers, method="POST")
        self.requests += 1
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as r:
                raw = r.read()
        except urllib.error.HTTPError as e:
            text = _read(e)
            low = text.lower().replace(" ", "_")
            # some servers answer an unknown response_format with 400/422, llama-cpp-python with 500
            if (
                mode != "none"
                and e.code in (400, 422, 500, 501)
                and ("response_format" in low or (e.code != 500 and ("json" in low or "schema" in low)))
            ):
                raise FormatUnsupported(text[:200]) from None
            if e.code in (408, 409, 425, 429) or e.code >= 500:
                raise ServerError(f"http_{e.code}", text[:200]) from None
            raise _Fatal(f"http_{e.code}", text[:200]) from None
        except TimeoutError as e:
            raise ServerError("timeout", str(e)) from None
        except (ConnectionError, http.client.HTTPException, urllib.error.URLError, OSError) as e:
            if isinstance(getattr(e, "reason", None), (TimeoutError, socket.timeout)):
                raise ServerError("timeout", str(e)) from None
            raise ServerError("connection", f"{type(e).__name__}: {e}") from None
        try:
            env = json.loads(raw)
            content = env["choices"][0]["message"]["content"]
        except (ValueError, KeyError, IndexError, TypeError) as e:
            raise ServerError("envelope", f"{type(e).__name__}: {raw[:120]!r}") from None
        if not isinstance(content, str):
            raise ServerError("envelope", "message content is not text")
        return content


class _Fatal(ServerError):
    """A client error (401, 404, ...): retrying cannot help."""


def _read(e: urllib.error.HTTPError) -> str:
    try:
        return e.read().decode("utf-8", "replace")
    except Exception:  # noqa: BLE001 - the error body is only a hint for the message
        return ""


def parse_reply(content: str) -> tuple[str, str | None] | None:
    """(question, answer) from the model's text: a JSON object (also inside code fences or prose), keys in
    any case. None when there is no JSON object with a text question."""
    obj = _json_object(content)
    if not isinstance(obj, dict):
        return None
    low = {str(k).strip().lower(): v for k, v in obj.items()}
    q, a = low.get("question"), low.get("answer")
    if not isinstance(q, str):
        return None
    return q, (a if isinstance(a, str) else (None if a is None else json.dumps(a)))


def _json_object(text: str) -> Any:
    try:
        return json.loads(text)
    except ValueError:
        pass
    i, j = text.find("{"), text.rfind("}")
    if 0 <= i < j:
        try:
            return json.loads(text[i : j + 1])
        except ValueError:
            return None
    return None
