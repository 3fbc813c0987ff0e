"""Shared by the hard-case examples: the scenes and references live in tests/hard_scenes.py."""

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))


def args(doc: str):
    ap = argparse.ArgumentParser(description=doc)
    ap.add_argument("--backend", default="casadi", choices=["casadi", "c"])
    ap.add_argument("--rule", default="trapezoid", choices=["trapezoid", "midpoint"])
    return ap.parse_args()
