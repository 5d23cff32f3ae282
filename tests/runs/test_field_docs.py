"""The docstrings under settings fields (a flag's help), read from the source wherever the class is."""

from __future__ import annotations

import dataclasses

from fleetrl.runs.setting_values import field_docs, setting_fields


@dataclasses.dataclass(frozen=True, kw_only=True)
class Outer:
    """A settings class with a settings class nested in it."""

    rounds: int = 3
    """how many rounds"""

    @dataclasses.dataclass(frozen=True, kw_only=True)
    class Inner:
        """A nested settings class."""

        rate: float = 0.5
        """the ``rate`` of :class:`Outer`"""


@dataclasses.dataclass(frozen=True, kw_only=True)
class Grouped(Outer):
    """A subclass holding a group: its own fields, its base's and its group's are documented."""

    inner: Outer.Inner = dataclasses.field(default_factory=Outer.Inner)
    name: str = "x"
    """a   name
    over two lines"""


def test_a_module_level_class_its_base_and_its_nested_group_have_their_docstrings() -> None:
    assert field_docs(Grouped) == {
        "rounds": "how many rounds",
        "name": "a name over two lines",
        "rate": "the rate of Outer",
    }
    assert field_docs(Outer.Inner) == {"rate": "the rate of Outer"}


def test_a_class_defined_in_a_function_has_its_docstrings() -> None:
    @dataclasses.dataclass(frozen=True, kw_only=True)
    class Local:
        seed: int = 0
        """the seed"""

    assert field_docs(Local) == {"seed": "the seed"}


def test_setting_fields_are_read_once_and_a_caller_cannot_change_them() -> None:
    fields = setting_fields(Grouped)
    assert list(fields) == ["rounds", "rate", "name"]  # a group's settings where the group is
    fields.clear()
    assert list(setting_fields(Grouped)) == ["rounds", "rate", "name"]
