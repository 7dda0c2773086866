"""Message limits: size, nesting depth (scanned before parsing), finite numbers, rate."""

from __future__ import annotations

import pytest

from emotive.serve.errors import MessageError
from emotive.serve.limits import TokenBucket, nesting_depth, parse_message


def test_nesting_depth_ignores_brackets_in_strings():
    assert nesting_depth('{"a": [1, {"b": "[[[[{{{{"}]}') == 3
    assert nesting_depth('{"a": "\\"[[[["}') == 1
    assert nesting_depth("plain") == 0


def test_ten_thousand_nested_brackets_are_refused_before_parsing():
    with pytest.raises(MessageError, match="10000 levels"):
        parse_message("[" * 10_000 + "]" * 10_000, 1_000_000, 64)
    assert parse_message('{"type": "x", "a": ' + "[" * 60 + "]" * 60 + "}", 1000, 64)


@pytest.mark.parametrize(("text", "match"), [
    ("not json", "not JSON"),
    ("[1, 2]", "JSON object"),
    ("{}", '"type"'),
    ('{"type": 3}', '"type"'),
    ('{"type": "x", "w": NaN}', "NaN"),
    ('{"type": "x", "w": -Infinity}', "Infinity"),
    ('{"type": "x", "w": 1e999}', "out of range"),
])
def test_bad_messages_are_named(text, match):
    with pytest.raises(MessageError, match=match):
        parse_message(text, 1000, 64)


def test_size_limit_counts_utf8_bytes():
    with pytest.raises(MessageError, match="larger than the limit of 100"):
        parse_message('{"type": "' + "é" * 60 + '"}', 100, 64)
    assert parse_message('{"type": "' + "e" * 60 + '"}', 100, 64)["type"] == "e" * 60


def test_token_bucket_allows_bursts_then_the_rate():
    now = [0.0]
    bucket = TokenBucket(rate=10, burst=5, clock=lambda: now[0])
    assert [bucket.take() for _ in range(6)] == [True] * 5 + [False]
    now[0] += 0.25
    assert [bucket.take() for _ in range(3)] == [True, True, False]
    now[0] += 100.0
    assert sum(bucket.take() for _ in range(10)) == 5
