"""lfjax.design.runner: the one loop of both design kinds (refusal, plan, make, report,
keeping and resuming), run with a stand-in kind that counts its calls (no optics)."""

from __future__ import annotations

from dataclasses import dataclass, field

from lfjax.design.fit import ONE_LENSLET_VIEW, LensletKind
from lfjax.design.lenticular import ONE_STRIP, LenticularKind
from lfjax.design.report import CountVerdict
from lfjax.design.runner import DesignKind, count_refusal, run_counts
from lfjax.design.settings import DesignConstraints
from lfjax.display.panel import phone_panel


@dataclass
class Count(CountVerdict):
    n: int
    panel: object = None
    refused: str | None = None
    failed: str | None = None
    score: dict | None = None


@dataclass
class CountingKind(DesignKind):
    """Makes every count at once, scores it by its n; ``failing`` counts fail their report."""

    panel: object
    cdp_D: float
    constraints: DesignConstraints = DesignConstraints()  # noqa: RUF009 (frozen)
    failing: tuple = ()
    tag: str = "a"
    calls: list = field(default_factory=list)

    counts_format = "test-count/1"
    counts_stem = "test"
    one_view = "one view"

    def key(self, n):
        return f"{self.tag}-{n}"

    def record(self, fit):
        return {"n": fit.n, "panel": fit.panel, "refused": fit.refused, "failed": fit.failed,
                "score": fit.score}

    def from_record(self, record):
        return Count(**record)

    def refused(self, n, why):
        return Count(n, refused=why)

    def plan(self, counts, kept, refusals, counts_dir, say):
        self.calls.append(("plan", sorted(kept), sorted(refusals)))

    def make(self, n, say):
        self.calls.append(("make", n))
        return Count(n, panel=f"panel {n}")

    def report(self, fit, n, say):
        self.calls.append(("report", n))
        fit.score = {"n": n}
        fit.failed = "too blurred" if n in self.failing else None


def test_each_count_is_refused_made_and_reported_once_in_order():
    """The plan comes first (with the refusals), then every count is made, then reported;
    refused counts are neither made nor reported; the result keeps the counts' order."""
    kind = CountingKind(phone_panel(cdp_D=2.0), 2.0, failing=(3,))
    fits = run_counts(kind, [1, 2, 3])
    assert kind.calls == [("plan", [], [1]), ("make", 2), ("make", 3), ("report", 2), ("report", 3)]
    assert [f.n for f in fits] == [1, 2, 3]
    assert fits[0].status == "refused: one view" and fits[1].ok
    assert fits[2].status == "fails: too blurred" and not fits[2].ok


def test_a_count_no_panel_makes_is_refused_before_anything():
    """Both kinds refuse the same counts: a CDP in front of the display at the panel's
    distance (no panel of these pixels makes it), and one view, each in its kind's words."""
    panel = phone_panel(cdp_D=2.0)  # 350 mm away: a CDP of 3 D (333 mm) lies in front of it
    assert count_refusal(CountingKind(panel, 3.0), 2).startswith("infeasible: at 350 mm the CDP 3 D")
    assert count_refusal(CountingKind(panel, 2.0), 1) == "one view"
    assert count_refusal(CountingKind(panel, 2.0), 2) is None
    assert LensletKind.one_view == ONE_LENSLET_VIEW and LenticularKind.one_view == ONE_STRIP
    assert LenticularKind.report_counts == "all" and LensletKind.counts_stem != LenticularKind.counts_stem


def test_made_counts_are_kept_and_a_later_run_with_the_same_key_resumes(tmp_path):
    """Each made count is kept (after it is made and again once reported), refusals are not;
    a run with the same keys makes and reports nothing; another key makes them again."""
    panel = phone_panel(cdp_D=2.0)
    first = CountingKind(panel, 2.0)
    run_counts(first, [1, 2, 3], tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["test-2.json", "test-3.json"]
    again = CountingKind(panel, 2.0)
    fits = run_counts(again, [1, 2, 3], tmp_path)
    assert again.calls == [("plan", [2, 3], [1])]
    assert [f.score for f in fits] == [None, {"n": 2}, {"n": 3}]
    other = CountingKind(panel, 2.0, tag="b")
    run_counts(other, [2], tmp_path)
    assert other.calls == [("plan", [], []), ("make", 2), ("report", 2)]


def test_a_count_kept_before_its_report_is_reported_when_resumed(tmp_path):
    """A run stopped between a count's making and its report keeps the made count; the next
    run reports it without making it again."""
    panel = phone_panel(cdp_D=2.0)

    class Stopped(CountingKind):
        def report(self, fit, n, say):
            raise KeyboardInterrupt

    try:
        run_counts(Stopped(panel, 2.0), [2], tmp_path)
    except KeyboardInterrupt:
        pass
    resumed = CountingKind(panel, 2.0)
    fits = run_counts(resumed, [2], tmp_path)
    assert resumed.calls == [("plan", [2], []), ("report", 2)] and fits[0].ok
