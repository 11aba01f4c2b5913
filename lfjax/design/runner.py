"""The one runner of a display design, whatever its kind: n×n lenslet views
(:class:`lfjax.design.fit.LensletKind`) or 1×n lenticular strips
(:class:`lfjax.design.lenticular.LenticularKind`).

For each count n of views the runner (:func:`run_counts`) loads a count kept by an earlier
call with the same inputs, refuses a count no panel of these pixels can make and one view
(:func:`count_refusal`), lets the kind say its plan, makes (fits) every other count, then
reports the made counts in the order :func:`lfjax.design.report.report_counts_in_order`
sets, keeping each count in ``counts_dir`` (:mod:`lfjax.design.resume`) as soon as it is made
and again once it is reported. What differs between the kinds — how a count is made and
scored, the label of a count, the wording of the one-view refusal, the record kept on disk
— is the kind's (:class:`DesignKind`); the loop, the resume and the order are here once.
"""

from __future__ import annotations

from lfjax.design.box import feasibility
from lfjax.design.report import report_counts_in_order
from lfjax.design.resume import load_count, save_count


class DesignKind:
    """What one kind of design does with a count; :func:`run_counts` calls these hooks, and
    each kind sets these attributes.

    Attributes
    ----------
    panel : the starting :class:`~lfjax.display.panel.Panel` (its pixels and distance are kept)
    cdp_D : the design's CDP, D
    constraints : :class:`~lfjax.design.settings.DesignConstraints`
    counts_format, counts_stem : the format tag and file-name stem of a kept count
        (``counts_dir/STEM-N.json``)
    one_view : the sentence refusing n = 1 (one view fills the pupil: no light field)
    report_counts : which made counts the report scores (``"chosen"`` or ``"all"``,
        :func:`~lfjax.design.report.report_counts_in_order`)
    """

    counts_format: str
    counts_stem: str
    one_view: str
    report_counts: str = "all"

    def key(self, n: int) -> str:
        """The digest naming everything count ``n`` depends on (:mod:`lfjax.design.resume`)."""
        raise NotImplementedError

    def record(self, fit) -> dict:
        """A count as JSON-ready data, kept on disk."""
        raise NotImplementedError

    def from_record(self, record: dict):
        """Inverse of :meth:`record`."""
        raise NotImplementedError

    def refused(self, n: int, why: str):
        """Count ``n`` refused before it is made, for the reason ``why``."""
        raise NotImplementedError

    def plan(self, counts: list, kept: set, refusals: dict, counts_dir, say) -> None:
        """Prepare what the counts to be made need and say the plan, before any is made:
        ``kept`` the counts loaded from ``counts_dir``, ``refusals`` {n: why} the refused ones.
        ``say``: a callable taking one line, or None."""
        raise NotImplementedError

    def make(self, n: int, say):
        """Count ``n`` made (fitted or set in closed form), its verdict from its geometry."""
        raise NotImplementedError

    def report(self, fit, n: int, say) -> None:
        """Score the made count ``fit`` (count ``n``) and complete its verdict, in place."""
        raise NotImplementedError


def count_refusal(kind: DesignKind, n: int) -> str | None:
    """Why ``n`` views are refused before anything is made (a sentence), or None: no panel
    of ``kind.panel``'s pixels makes them (:func:`~lfjax.design.box.feasibility`), or one
    view, which is one aperture whatever the lenses (``kind.one_view``). Both kinds refuse
    the same counts."""
    why = feasibility(kind.panel, n, kind.cdp_D, kind.constraints)
    if why is not None:
        return f"infeasible: {why}"
    return kind.one_view if n == 1 else None


def run_counts(kind: DesignKind, counts, counts_dir=None, say=None) -> list:
    """Every count of ``counts`` made and reported by ``kind`` (module docstring), in the
    order of ``counts``. ``counts_dir``: a folder where each made count is kept (None:
    nothing kept); a count kept there with the same key is loaded instead of made again.
    ``say``: a callable taking one line, or None."""
    counts = [int(n) for n in counts]
    keys, fits = {}, {}
    if counts_dir is not None:
        for n in counts:
            keys[n] = kind.key(n)
            found = load_count(counts_dir, kind, n, keys[n])
            if found is not None:
                fits[n] = found
    kept = set(fits)
    refusals = {n: why for n in counts if n not in kept
                for why in [count_refusal(kind, n)] if why is not None}
    kind.plan(counts, kept, refusals, counts_dir, say)
    # Every count made first, then the report of those the question reads: for the n×n
    # design the report's transforms are most of a count's cost.
    for n in counts:
        if n in kept:
            continue
        if n in refusals:  # not kept: the refusal costs nothing to find again
            fits[n] = kind.refused(n, refusals[n])
            continue
        fits[n] = kind.make(n, say)
        if counts_dir is not None:  # kept at once: a later failure or Ctrl-C loses no count
            save_count(counts_dir, kind, keys[n], n, fits[n])
    count_of = {id(f): n for n, f in fits.items()}

    def report_one(one) -> None:
        n = count_of[id(one)]
        kind.report(one, n, say)
        if counts_dir is not None:
            save_count(counts_dir, kind, keys[n], n, one)

    ordered = [fits[n] for n in counts]
    report_counts_in_order(ordered, report_one, kind.report_counts)
    return ordered


__all__ = ["DesignKind", "count_refusal", "run_counts"]
