"""The search space of `robocup-mcl tune`: which profile settings to tune, over which ranges.

A space file is TOML with the sections of a profile (`mcl.profile.SECTIONS`); each setting to tune is an
inline table:

    [sensor]
    range_noise_floor = { low = 0.02, high = 0.2, log = true }    # sampled on a log scale
    outlier_weight = { low = 0.001, high = 0.1, log = true }
    mixture = { choices = ["max", "sum"] }                          # a setting with a few values

    [augmented]
    fit_threshold = { low = 0.0, high = 0.5 }

    [localizer]
    particles = { low = 100, high = 1000, log = true }              # an integer setting: integers drawn

Anything else in the file is an error: a section or setting a profile does not have, `low` >= `high`, `log`
with `low` <= 0, a value the library refuses (a range end that makes a negative noise, say), or a
missing `low`/`high`. Each error is one line naming the file and the setting (`SpaceError`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from mcl.profile import SECTIONS, Profile, ProfileError, parse_toml, read_text


class SpaceError(ValueError):
    """A space file that cannot be searched (one line naming the file and the setting)."""


@dataclass(frozen=True)
class Parameter:
    """One tuned setting: `name` "section.setting", a range [low, high] (on a log scale when `log`) of
    `kind` float or int, or `choices`."""

    name: str
    kind: type
    low: float = 0.0
    high: float = 0.0
    log: bool = False
    choices: tuple = ()

    def distribution(self):
        """The Optuna distribution of this parameter."""
        import optuna

        if self.choices:
            return optuna.distributions.CategoricalDistribution(self.choices)
        if self.kind is int:
            return optuna.distributions.IntDistribution(int(self.low), int(self.high), log=self.log)
        return optuna.distributions.FloatDistribution(float(self.low), float(self.high), log=self.log)

    def describe(self) -> str:
        """ "sensor.outlier_weight in [0.001, 0.1] (log)" and the like."""
        if self.choices:
            return f"{self.name} in {{{', '.join(map(repr, self.choices))}}}"
        return f"{self.name} in [{self.low:g}, {self.high:g}]" + (" (log)" if self.log else "")


@dataclass(frozen=True)
class SearchSpace:
    """The parameters of a space file, in the file's order."""

    parameters: tuple[Parameter, ...]
    source: str = ""

    @property
    def names(self) -> list[str]:
        """The parameters' names, "section.setting"."""
        return [p.name for p in self.parameters]

    def distributions(self) -> dict:
        """{name: Optuna distribution}."""
        return {p.name: p.distribution() for p in self.parameters}

    def to_dict(self) -> dict:
        """JSON-ready: per parameter its range or choices."""
        return {
            p.name: (
                {"choices": list(p.choices)}
                if p.choices
                else {"low": p.low, "high": p.high, "log": p.log, "int": p.kind is int}
            )
            for p in self.parameters
        }

    @classmethod
    def load(cls, path: str | os.PathLike) -> SearchSpace:
        """The space in the TOML file `path` (OSError if unreadable, SpaceError if wrong)."""
        return cls.from_toml(*read_text(path))

    @classmethod
    def from_toml(cls, text: str, source: str = "") -> SearchSpace:
        """The space in TOML `text` (`source` names it in errors)."""
        return cls.from_dict(parse_toml(text, source, SpaceError), source)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "") -> SearchSpace:
        """The space of {section: {setting: {"low", "high", "log"} or {"choices"}}}."""
        where = f"{source}: " if source else ""
        parameters = []
        for section, settings in data.items():
            if section not in SECTIONS:
                raise SpaceError(f"{where}unknown section [{section}]; known: {', '.join(SECTIONS)}")
            if not isinstance(settings, Mapping):
                raise SpaceError(f"{where}[{section}] must be a table of settings")
            for name, spec in settings.items():
                parameters.append(_parameter(where, section, name, spec))
        if not parameters:
            raise SpaceError(f"{where}the space names no setting to tune")
        for p in parameters:
            _check_ends(where, p, parameters)
        return cls(tuple(parameters), source)


def _parameter(where: str, section: str, name: str, spec: Any) -> Parameter:
    full = f"{section}.{name}"
    if name not in SECTIONS[section]:
        raise SpaceError(f"{where}[{section}] unknown setting {name!r}; known: {', '.join(SECTIONS[section])}")
    if not isinstance(spec, Mapping):
        raise SpaceError(f"{where}{full} = {spec!r} must be a table: {{ low = .., high = .. }} or {{ choices = [..] }}")
    kind = SECTIONS[section][name]
    extra = set(spec) - {"low", "high", "log", "choices"}
    if extra:
        raise SpaceError(f"{where}{full}: unknown key {sorted(extra)[0]!r} (low, high, log or choices)")
    if "choices" in spec:
        choices = spec["choices"]
        if set(spec) != {"choices"} or not isinstance(choices, list) or not choices:
            raise SpaceError(f"{where}{full}: choices must be a non-empty list, alone")
        return Parameter(full, kind, choices=tuple(choices))
    if kind not in (int, float):
        raise SpaceError(f"{where}{full} is not a number: give its choices = [..]")
    if "low" not in spec or "high" not in spec:
        raise SpaceError(f"{where}{full}: needs low and high")
    low, high, log = spec["low"], spec["high"], spec.get("log", False)
    for key, value in (("low", low), ("high", high)):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or value != value
            or abs(value) == float("inf")
        ):
            raise SpaceError(f"{where}{full}: {key} = {value!r} must be a finite number")
        if kind is int and float(value) != int(value):
            raise SpaceError(f"{where}{full}: {key} = {value!r} must be an integer (the setting is one)")
    if not isinstance(log, bool):
        raise SpaceError(f"{where}{full}: log = {log!r} must be true or false")
    if not low < high:
        raise SpaceError(f"{where}{full}: low = {low!r} must be below high = {high!r}")
    if log and low <= 0:
        raise SpaceError(f"{where}{full}: a log scale needs low > 0, not {low!r}")
    return Parameter(full, kind, float(low), float(high), bool(log))


def _ends(p: Parameter) -> list:
    if p.choices:
        return list(p.choices)
    return [int(p.low), int(p.high)] if p.kind is int else [p.low, p.high]


def _check_ends(where: str, p: Parameter, parameters: list[Parameter]) -> None:
    """SpaceError unless each end (or choice) of `p` is accepted by the library: alone, or with every other
    parameter of the space at its low end, or at its high end (settings that are checked together, such as
    alpha_slow < alpha_fast)."""
    others = [q for q in parameters if q is not p]
    contexts = [{}, {q.name: _ends(q)[0] for q in others}, {q.name: _ends(q)[-1] for q in others}]
    for value in _ends(p):
        error: ProfileError | None = None
        for context in contexts:
            try:
                Profile.from_values({**context, p.name: value})
                break
            except ProfileError as refused:
                error = error or refused
        else:
            raise SpaceError(f"{where}{p.name}: {value!r} is refused: {error}")
