"""The error a library check raises for a refused parameter value, naming the parameter.

:class:`ParameterError` is a ``ValueError`` whose message names the library's parameter
(``"n_depths must be >= 2 for a depth range, got 1"``), so a caller of the library reads the
name it passed. It also keeps the parameter apart from the sentence: the message is a
template whose fields are either values or parameter names, and :meth:`ParameterError.naming`
renders it with other names for the parameters. The command line renders it with its
flags, through one declared table (:data:`lfjax.cli.flags.FLAGS`), never by editing
message text::

    err = ParameterError("n_depths", "{n_depths} must be >= 2 for a depth range, got {got}", got=1)
    str(err)                                    # 'n_depths must be >= 2 for a depth range, got 1'
    err.naming({"n_depths": "--n-depths"})      # '--n-depths must be >= 2 for a depth range, got 1'

A message may name other parameters too (``"{front} needs held-out eyes ({test_eyes} >= 1)"``):
every field of the template that is not a value is a parameter (:attr:`parameters`).
"""

from __future__ import annotations

import string
from collections.abc import Mapping


class ParameterError(ValueError):
    """A parameter's value refused by a library check.

    Parameters
    ----------
    parameter : the library's name of the refused parameter (a keyword, a field)
    template : the message, a :meth:`str.format` template: each field is a value given in
        ``values`` or the name of a parameter (``parameter`` itself, or another the message
        refers to), rendered as :meth:`naming` is told
    owner : written before a parameter's library name (``"Panel"``: ``Panel.fill``);
        not before a name that :meth:`naming` is given
    values : the values the template shows (formatted with the field's spec)
    """

    def __init__(self, parameter: str, template: str, *, owner: str | None = None, **values):
        self.parameter = parameter
        self.template = template
        self.owner = owner
        self.values = values
        super().__init__(self.naming())

    @property
    def parameters(self) -> tuple[str, ...]:
        """Every parameter the message names: :attr:`parameter` first, then the others in
        the order they appear."""
        fields = [f for _, f, _, _ in string.Formatter().parse(self.template) if f]
        named = [f for f in fields if f not in self.values]
        return tuple(dict.fromkeys([self.parameter, *named]))

    def naming(self, names: Mapping[str, str] | None = None) -> str:
        """The message with each parameter named as ``names`` says (default, and for a
        parameter ``names`` lacks: its library name, after ``owner.`` when given)."""
        names = {} if names is None else names
        shown = {p: names.get(p) or (f"{self.owner}.{p}" if self.owner else p)
                 for p in self.parameters}
        return self.template.format_map({**shown, **self.values})

    def __reduce__(self):  # pickles (multiprocessing) with its keywords
        return _rebuild, (type(self), self.parameter, self.template, self.owner, self.values)


def _rebuild(cls, parameter, template, owner, values):
    return cls(parameter, template, owner=owner, **values)


FLAT_CURVE_RANGE = 1e-4
"""Relative range, (max − min)/max over a through-focus curve's states, below which its peak
is undetermined (:class:`FlatCurveWarning`): ten times finer than the planner's default VSOTF
accuracy (``lfjax.planner.targets.Targets.vsotf``, 1e-3), so the sampling's own error could
move the peak anywhere on such a curve; float32 rounding (1e-7) is far below it. Such curves
come from a pupil or views so small that defocus barely changes the image (a 0.01 mm pupil:
the depth of focus spans hundreds of dioptres)."""


class FlatCurveWarning(UserWarning):
    """A through-focus curve too flat for its peak to be a result (range below
    :data:`FLAT_CURVE_RANGE` of its maximum): its grid peak is the first state of the grid
    and its predicted accommodation, error and cut-off are undetermined."""


__all__ = ["ParameterError", "FlatCurveWarning", "FLAT_CURVE_RANGE"]
