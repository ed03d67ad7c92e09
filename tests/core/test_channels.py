"""The recording's channel table: one home for every topic and its schema."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hapticframe.kinds import SampleBatch
from hapticframe.record._recording import SCHEMAS, RunRecording, read_recording
from hapticframe.run._channels import (
    CHANNELS,
    METRICS,
    SENSOR,
    ChannelError,
    channel_of,
    check_topic,
)

ROOT = Path(__file__).resolve().parents[2]


def _doc_rows() -> list[tuple[str, str, str]]:
    """(topic, schema, written by) of docs/recording.md's channel table."""
    text = (ROOT / "docs" / "recording.md").read_text(encoding="utf-8")
    table = text[text.index("| topic | schema | written by |"):].split("\n\n")[0]
    rows = []
    for line in table.splitlines()[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows.append((cells[0].strip("`"), cells[1].strip("*").strip("`"), cells[2]))
    return rows


def test_the_docs_list_every_channel_of_the_table_in_its_order():
    expected = [(c.name.replace("{id}", "ID"), c.schema, c.writer) for c in CHANNELS]
    assert _doc_rows() == expected


def test_every_channel_has_a_schema_and_one_name():
    assert len({c.name for c in CHANNELS}) == len(CHANNELS)
    for channel in CHANNELS:
        assert channel.schema in SCHEMAS, channel.name
        assert channel.encoding == "json"
        # every concrete topic of the channel belongs to it and to no other
        topic = channel.topic("a-b_1") if channel.has_id else channel.topic()
        assert channel_of(topic) is channel
        assert channel.id_of(topic) == ("a-b_1" if channel.has_id else "")


def test_a_topic_outside_the_table_or_with_another_schema_is_refused():
    assert check_topic("/sensor/ft", "hapticframe.SampleBatch") is SENSOR
    with pytest.raises(ChannelError, match=r"has 'hapticframe\.SampleBatch'"):
        check_topic("/sensor/ft", "hapticframe.RunMetrics")
    with pytest.raises(ChannelError, match="in no channel"):
        check_topic("/sensors/ft", "hapticframe.SampleBatch")
    with pytest.raises(ChannelError, match="in no channel"):
        check_topic("/sensor/a/b", "hapticframe.SampleBatch")  # an id holds no '/'
    with pytest.raises(ChannelError, match="takes an id"):
        SENSOR.topic()
    with pytest.raises(ChannelError, match="takes no id"):
        METRICS.topic("x")


def test_the_writer_refuses_a_topic_with_another_schema(tmp_path):
    recording = RunRecording(tmp_path / "a.mcap")
    recording.samples("sensor", "ft", SampleBatch(np.array([0.1, 0.2]),
                                                  {"force_n": np.ones((2, 3))}))
    recording.event(METRICS.name, METRICS.schema, {"metrics": {}, "components": {}})
    # the same topic, once registered, still may not change its schema
    with pytest.raises(ChannelError, match="/metrics"):
        recording.event(METRICS.name, "hapticframe.SafetyHalt", {"reason": "x"})
    with pytest.raises(ChannelError, match="/sensor/ft"):
        recording.event("/sensor/ft", "hapticframe.SafetyHalt", {"reason": "x"})
    with pytest.raises(ChannelError, match="in no channel"):
        recording.event("/my/topic", "hapticframe.SafetyHalt", {"reason": "x"})
    recording.close()
    recorded = read_recording(tmp_path / "a.mcap")
    assert sorted(recorded) == ["/metrics", "/sensor/ft"]
    assert len(recorded["/metrics"]) == 1
