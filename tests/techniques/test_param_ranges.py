"""Every declared parameter of every registered technique refuses what its declaration forbids,
generated from the technique's own ``PARAMS`` (:class:`shadowlab.techniques.base.Param`): a
misspelt name (with the real one suggested), a value of the wrong type, a value outside its
``choices``, below its ``min`` (or at it, when the bound is open) or above its ``max`` — each a
one-line TechniqueError naming the technique and the parameter — while its default is accepted
and survives ``spec()`` → ``from_spec``. A new technique is covered without a line here; the
technique test files keep only the checks across parameters that no single declaration says."""
from __future__ import annotations

import re

import pytest

from shadowlab.techniques import REGISTRY, TechniqueError, from_spec
from shadowlab.techniques.base import format_value


def _bad_values(param) -> list[tuple[str, str]]:
    """(spec value, the message it must give) for every rule ``param`` declares."""
    kind = type(param.default)
    out = []
    if kind is bool:
        out.append(("maybe", "must be bool"))
    elif kind is int:
        out.append(("2.5", "must be int"))
    elif kind is float:
        out += [("abc", "must be float"), ("nan", "must be float")]
    if param.choices is not None:
        outside = "no_such_choice" if kind is str else format_value(kind(max(param.choices) + 1))
        out.append((outside, "must be one of"))
    if param.min is not None:
        low = param.min if param.min_open else param.min - (1 if kind is int else max(1.0, abs(param.min)))
        out.append((format_value(kind(low)), f"must be {'>' if param.min_open else '>='} "))
    if param.max is not None:
        high = param.max + (1 if kind is int else max(1.0, abs(param.max)))
        out.append((format_value(kind(high)), "must be <= "))
    return out


def _first_declarations() -> list[tuple[str, str, object]]:
    """(technique, key, Param) for every declaration, a Param object shared under the same key by
    several techniques (light_samples, the map family's contact parameters, the comparison
    parameters of shadow_map and lispsm) only on the first of them: it parses the same wherever it
    is declared, and checking it eleven times would only slow the inner loop."""
    seen, out = set(), []
    for name, cls in REGISTRY.items():
        for key, param in cls.PARAMS.items():
            if (key, id(param)) not in seen:
                seen.add((key, id(param)))
                out.append((name, key, param))
    return out


CASES = [(name, key, value, message) for name, key, param in _first_declarations()
         for value, message in _bad_values(param)]
KEYS = [(name, key) for name, key, _ in _first_declarations()]


@pytest.mark.parametrize("name,key,value,message", CASES, ids=[f"{n}:{k}={v}" for n, k, v, _ in CASES])
def test_a_value_the_declaration_forbids_is_refused_naming_the_parameter(name, key, value, message):
    with pytest.raises(TechniqueError) as exc:
        from_spec(f"{name}:{key}={value}")
    text = str(exc.value)
    assert text.startswith(f"{name}: {key} ") and message in text and "\n" not in text, text


@pytest.mark.parametrize("name,key", KEYS, ids=[f"{n}:{k}" for n, k in KEYS])
def test_a_misspelt_parameter_is_refused_with_the_real_name(name, key):
    wrong = key[:-1] + ("x" if key[-1] != "x" else "y")
    with pytest.raises(TechniqueError, match=rf"^{name}: unknown parameter '{re.escape(wrong)}'.*{re.escape(key)}"):
        from_spec(f"{name}:{wrong}={format_value(REGISTRY[name].PARAMS[key].default)}")


@pytest.mark.parametrize("name,key", KEYS, ids=[f"{n}:{k}" for n, k in KEYS])
def test_the_default_is_accepted_and_round_trips(name, key):
    param = REGISTRY[name].PARAMS[key]
    tech = from_spec(f"{name}:{key}={format_value(param.default)}")
    assert tech.params()[key] == param.default
    assert from_spec(tech.spec()).params() == tech.params()


def test_the_generated_cases_cover_every_kind_of_rule():
    """The generator is not vacuous: the registry's declarations give it type, choice, min and
    max cases, on every registered technique that has parameters."""
    messages = {m.split()[2] for *_, m in CASES}
    assert {"bool", "int", "float", "one", ">=", "<="} <= messages, messages
    assert {n for n, *_ in CASES} == {n for n, cls in REGISTRY.items() if cls.PARAMS}
