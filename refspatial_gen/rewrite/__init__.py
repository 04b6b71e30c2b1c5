"""LLM rewriting of template questions on any OpenAI-compatible server, every rewrite re-checked.

Modules: `config` (the recipe's `rewrite:` section), `prompts` (per-family prompt files under
recipes/rewrite/), `facts` (what a pair's rewrite must keep), `client` (HTTP, retries, JSON formats),
`cache` (replies on disk by request), `check` (the acceptance rules), `stage` (the pipeline stage),
`dataset` (`refspatial-gen rewrite DIR --out DIR2`), `verify` (verify's re-check of stored rewrites),
`language` (the distinct-question share). See docs/rewrite.md.
"""
