"""The recipe's `rewrite:` section: which server and model, which pairs, sampling, limits, cache.

Checked with the recipe (schema.Field), so a wrong key or value is a `file:line` error before any work.
The prompt file is loaded and checked here too, and becomes part of the recipe hash.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import RecipeError, RecipeErrors
from refspatial_gen.rewrite.check import Limits
from refspatial_gen.rewrite.prompts import Prompts, load_prompts
from refspatial_gen.schema import Field, check_section
from refspatial_gen.yamlpos import line_of

SERVER_ENV = "REFSPATIAL_REWRITE_SERVER"  # overrides `server:` (e.g. a GPU box for one run)
SKIP_FAMILIES = ("point_depth",)  # questions whose body carries points: nothing to reword safely

FIELDS: dict[str, Field] = {
    "enabled": Field(bool, default=True, doc="false: the section is ignored (output as without it)"),
    "server": Field(str, default="http://127.0.0.1:8080/v1", doc="OpenAI-compatible base URL (.../v1)"),
    "model": Field(str, required=True, doc="model id sent to the server; part of every cache key"),
    "api_key_env": Field(str, default=None, doc="name of the environment variable holding an API key"),
    "prompts": Field(
        str, default=None, doc="prompt file, relative to the recipe (default recipes/rewrite/prompts.yaml)"
    ),
    "families": Field(list, default=None, doc="families to rewrite (default: all but point_depth)"),
    "share": Field(float, default=1.0, min=0.0, max=1.0, doc="share of eligible pairs sent (chosen by qa_id hash)"),
    "temperature": Field(float, default=0.2, min=0.0, max=2.0),
    "top_p": Field(float, default=1.0, min=0.0, max=1.0),
    "max_tokens": Field(int, default=160, min=16, max=4096),
    "seed": Field(int, default=0, min=0, doc="mixed with each qa_id into the per-request seed"),
    "response_format": Field(str, default="auto", choices=("auto", "json_schema", "json_object", "none")),
    "concurrency": Field(int, default=4, min=1, max=256, doc="requests in flight per worker process"),
    "timeout": Field(float, default=60.0, min=0.1, doc="seconds per request attempt"),
    "retries": Field(int, default=3, min=0, max=20),
    "backoff": Field(float, default=0.5, min=0.0, doc="first retry delay; doubles per attempt"),
    "backoff_max": Field(float, default=8.0, min=0.0),
    "cache": Field(str, default=None, doc="reply cache folder, relative to the recipe (default OUT/rewrite_cache)"),
    "max_chars": Field(int, default=320, min=16),
    "max_ratio": Field(float, default=2.5, min=1.0),
}

DEFAULT_PROMPTS = Path(__file__).resolve().parents[2] / "recipes" / "rewrite" / "prompts.yaml"


@dataclass(frozen=True)
class RewriteConfig:
    server: str
    model: str
    api_key_env: str | None
    prompts: Prompts
    families: tuple[str, ...] | None
    share: float
    sampling: dict[str, Any]  # temperature, top_p, max_tokens: sent with every request, part of the key
    seed: int
    response_format: str
    concurrency: int
    timeout: float
    retries: int
    backoff: float
    backoff_max: float
    cache: str | None
    limits: Limits
    source_files: tuple[str, ...] = ()

    def base_url(self) -> str:
        return os.environ.get(SERVER_ENV) or self.server

    def api_key(self) -> str | None:
        return os.environ.get(self.api_key_env) if self.api_key_env else None

    def wants(self, family: str) -> bool:
        if self.families is not None:
            return family in self.families
        return family not in SKIP_FAMILIES


def load_rewrite_config(data: Any, file: str, lines: dict, path: tuple = ("rewrite",)) -> RewriteConfig | None:
    """Compile a `rewrite:` mapping (None when `enabled: false`). Raises RecipeErrors."""
    errors: list[RecipeError] = []
    sec = check_section(data, FIELDS, file, lines, path, errors)
    if errors:
        raise RecipeErrors(errors)
    if not sec["enabled"]:
        return None
    base = Path(file).resolve().parent
    pfile = (base / sec["prompts"]).resolve() if sec["prompts"] else DEFAULT_PROMPTS
    if not pfile.is_file():
        raise RecipeError(file, line_of(lines, path + ("prompts",)), f"prompt file {pfile} not found")
    prompts = load_prompts(pfile)
    fams = sec["families"]
    if fams is not None and not all(isinstance(f, str) for f in fams):
        raise RecipeError(file, line_of(lines, path + ("families",)), "families must list family names")
    cache = str((base / sec["cache"]).resolve()) if sec["cache"] else None
    return RewriteConfig(
        server=sec["server"],
        model=sec["model"],
        api_key_env=sec["api_key_env"],
        prompts=prompts,
        families=None if fams is None else tuple(fams),
        share=sec["share"],
        sampling={"temperature": sec["temperature"], "top_p": sec["top_p"], "max_tokens": sec["max_tokens"]},
        seed=sec["seed"],
        response_format=sec["response_format"],
        concurrency=sec["concurrency"],
        timeout=sec["timeout"],
        retries=sec["retries"],
        backoff=sec["backoff"],
        backoff_max=sec["backoff_max"],
        cache=cache,
        limits=Limits(sec["max_chars"], Limits.min_chars, sec["max_ratio"]),
        source_files=(str(pfile),),
    )


def load_rewrite_file(path: str | Path) -> RewriteConfig | None:
    """The `rewrite:` section of a recipe or of a file holding only that section."""
    from refspatial_gen.yamlpos import load_yaml

    data, lines = load_yaml(path)
    if not isinstance(data, dict) or "rewrite" not in data:
        raise RecipeError(str(path), 1, "no `rewrite:` section in this file")
    return load_rewrite_config(data["rewrite"], str(path), lines)
