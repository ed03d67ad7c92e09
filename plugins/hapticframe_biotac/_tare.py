"""Tare of BioTac recordings: the kernel's causal tare (:mod:`hapticframe.tare`).

BioTac users zero the sensor before every trial, because each fingertip (and each
re-inflation of its skin) rests at its own counts: the resting electrode pattern differs by
hundreds of counts between fingertips and by tens between trials (see
``docs/synthetic-biotac.md``). The same tare serves the ``recording`` sensor, so that a
BioTac bag replayed through it is zeroed exactly as the BioTac replay zeroes a CSV.
"""

from __future__ import annotations

from hapticframe.tare import TareState, tare_reference

__all__ = ["TareState", "tare_reference"]
