"""Audit: a stratified sample of QA pairs judged by eye against the picture, and the rates it gives.

`verify` proves answers agree with the scene model; only a person looking at the picture can tell whether
the scene model agrees with the picture. This package picks the sample (`sample.py`), renders the review
page (`page.py`), serves it so verdicts land in a file (`serve.py`) and summarises them (`verdicts.py`).
"""
