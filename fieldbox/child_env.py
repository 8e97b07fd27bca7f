"""The environment of a program fieldbox starts for the user (``fieldbox run --launch``,
conform's hooks): this install's commands first on PATH.

A README command such as ``--launch "fieldbox ..."`` or ``--launch "python -m robotpy ..."``
then names this fieldbox and this interpreter, as it does in an activated virtual
environment, also when fieldbox was started as ``.venv/bin/fieldbox`` without activating it.
"""

from __future__ import annotations

import os
import sys


def child_env(**extra: str) -> dict[str, str]:
    """``os.environ`` with the folder of this interpreter (a venv's ``bin``) first on PATH,
    and ``extra`` on top."""
    here = os.path.dirname(sys.executable)
    path = os.environ.get("PATH", os.defpath)
    parts = [p for p in path.split(os.pathsep) if p and os.path.abspath(p) != here]
    return dict(os.environ, PATH=os.pathsep.join([here, *parts]), **extra)
