"""Which features a model offers: its cylinder links, tracked edges and tips by name.

The feature tracker's default set is every one of them but :data:`THESIS_EXCLUDED_LINKS`;
the feature-based size measurement (:mod:`digiteyes.trackers.feature_size`) uses the same
set for every tracker.
"""

from __future__ import annotations

from collections.abc import Sequence

from digiteyes.kinematics import KinematicModel

THESIS_EXCLUDED_LINKS = ("middle.proximal", "ring.proximal")
"""Links the thesis's whole-hand experiment did not measure (Sec. 4.3.3: the proximal
phalanges of the middle two fingers, which were always occluded). In the Appendix A model
they also interpenetrate (anchors 15 mm apart, radii 10 + 9 mm), so the silhouette edges
between them do not exist; the default feature set leaves them out too."""


def all_features(model: KinematicModel) -> tuple[str, ...]:
    """Every cylinder link, tracked edge and tip of ``model``."""
    return tuple(link.name for link in model.links if link.kind in ("link", "edge", "tip"))


def thesis_whole_hand_links(model: KinematicModel) -> tuple[str, ...]:
    """Every cylinder link and tip of ``model`` except :data:`THESIS_EXCLUDED_LINKS`:
    the 13 phalanges and 5 tips of thesis Sec. 4.3.3 for the full hand (no palm edges,
    which the thesis did not measure)."""
    return tuple(link.name for link in model.links
                 if link.kind in ("link", "tip") and link.name not in THESIS_EXCLUDED_LINKS)


def feature_names(model: KinematicModel, names: Sequence[str] | None = None
                  ) -> tuple[list[str], list[str]]:
    """The cylinder links (and tracked edges) and the tips to measure: those of
    ``names`` (a :class:`ValueError` naming the unknown ones), or for None every one but
    :data:`THESIS_EXCLUDED_LINKS` (the feature tracker's default set)."""
    features = [link for link in model.links if link.kind in ("link", "edge", "tip")]
    if names is None:
        chosen = [link for link in features if link.name not in THESIS_EXCLUDED_LINKS]
    else:
        by_name = {link.name: link for link in features}
        unknown = [n for n in names if n not in by_name]
        if unknown:
            raise ValueError(
                f"model {model.name!r} has no cylinder link or tip named "
                f"{', '.join(map(repr, unknown))}; choose from "
                f"{', '.join(by_name)}"
            )
        chosen = [by_name[n] for n in dict.fromkeys(names)]
    links = [link.name for link in chosen if link.kind in ("link", "edge")]
    tips = [link.name for link in chosen if link.kind == "tip"]
    if not links and not tips:
        raise ValueError(f"no cylinder link or tip to track in model {model.name!r}")
    return links, tips


__all__ = ["THESIS_EXCLUDED_LINKS", "all_features", "feature_names", "thesis_whole_hand_links"]
