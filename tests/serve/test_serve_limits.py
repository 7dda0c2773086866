"""Message limits: size, nesting depth (scanned before parsing), finite numbers, rate."""

from __future__ import annotations

import pytest

from emotive.serve.errors import NO_REF, MessageError
from emotive.serve.limits import (
    TokenBucket,
    WorkBudget,
    head_ref,
    nesting_depth,
    parse_message,
    ref_of,
)


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


@pytest.mark.parametrize("text", [
    '{"type": "add_agent", "pace": NaN, "ref": [1, "a"]}',
    '{"ref": [1, "a"], "type": "set_target", "id": 0, "target": [-Infinity, 1e999]}',
])
def test_a_refusal_for_non_finite_numbers_keeps_the_ref(text):
    with pytest.raises(MessageError, match="finite numbers") as caught:
        parse_message(text, 1000, 64)
    assert caught.value.ref == [1, "a"]


def test_ref_of_text_that_is_no_object_is_none():
    assert ref_of("not json") is NO_REF and ref_of("[1, NaN]") is NO_REF
    assert ref_of('{"type": "x"}') is NO_REF and ref_of('{"ref": 0, "x": NaN}') == 0


def test_values_are_counted_before_parsing():
    text = '{"type": "x", "v": [' + ", ".join(["1"] * 30) + "]}"
    with pytest.raises(MessageError, match="about 31 values; the limit is 20"):
        parse_message(text, 10_000, 64, max_values=20)
    assert len(parse_message(text, 10_000, 64, max_values=40)["v"]) == 30


def test_work_budget_refuses_while_overdrawn_then_refills():
    now = [0.0]
    budget = WorkBudget(rate=0.1, burst=0.5, clock=lambda: now[0])
    assert budget.allowed()
    budget.charge(0.8)
    assert not budget.allowed()
    now[0] += 2.0
    assert not budget.allowed()
    now[0] += 1.5
    assert budget.allowed()
    now[0] += 100.0
    budget.charge(0.49)
    assert budget.allowed()


def test_token_bucket_delay_is_the_wait_for_one_token():
    now = [0.0]
    bucket = TokenBucket(rate=10, burst=2, clock=lambda: now[0])
    assert bucket.delay() == 0.0
    assert bucket.take() and bucket.take() and not bucket.take()
    assert bucket.delay() == pytest.approx(0.1)
    now[0] += 0.05
    assert bucket.delay() == pytest.approx(0.05)


@pytest.mark.parametrize(("text", "ref"), [
    ('{"ref": 7, "type": "set_path", "points": [' + "[1, 2], " * 50_000, 7),
    ('{"type": "set_emotion", "ref": "a\\"b}", "keyframes": [', 'a"b}'),
    ('{ "ref" : [1, "a"], "type": "x", "v": [' + "1, " * 100, [1, "a"]),
    ('{"type": "ref", "a": {"ref": 3}, "v": [', NO_REF),    # "ref" as a value, a nested key
    ('[{"ref": 1}, ', NO_REF),
    ('{"ref": NaN, "type": "x"', NO_REF),
    ('{"ref": [1, 1e999], "type": "x"', NO_REF),
    ('{"pad": "' + "x" * 300 + '", "ref": 5}', NO_REF),     # beyond the head
])
def test_the_ref_of_a_message_too_large_to_parse_is_read_from_its_head(text, ref):
    assert head_ref(text) == ref if ref is not NO_REF else head_ref(text) is NO_REF


def test_refusals_before_parsing_carry_the_ref_from_the_head():
    many = '{"ref": 9, "type": "x", "v": [' + ", ".join(["1"] * 30) + "]}"
    with pytest.raises(MessageError, match="about 32 values") as caught:
        parse_message(many, 10_000, 64, max_values=20)
    assert caught.value.ref == 9
    deep = '{"ref": "d", "type": "x", "v": ' + "[" * 80 + "]" * 80 + "}"
    with pytest.raises(MessageError, match="nested 81 levels") as caught:
        parse_message(deep, 10_000, 64)
    assert caught.value.ref == "d"
    with pytest.raises(MessageError, match="not JSON") as caught:
        parse_message('{"ref": 3, "type": "x", "v": [1, 2', 10_000, 64)
    assert caught.value.ref == 3
