"""Argument types shared by the ``gcs`` commands (one refusal wording for every command)."""

from __future__ import annotations

import argparse


def whole_number(minimum: int):
    """An argparse type: a whole number of at least ``minimum``, with a one-line refusal."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
        if v < minimum:
            raise argparse.ArgumentTypeError(f"must be ≥ {minimum}, not {v}")
        return v

    return parse


def seconds_or_zero(text: str) -> float:
    """An argparse type: a finite number of seconds ≥ 0 (0 turns the option's feature off)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number of seconds: {text!r}") from None
    if not (v >= 0 and v != float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number ≥ 0, not {text}")
    return v
