"""Scoring an estimator's data association against the ids a stream carries (ids it was not allowed to use, or
hidden true ids: ``truth_landmark``)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

from online_slam.estimators.protocol import Estimate
from online_slam.sources.events import LandmarkId
from online_slam.sources.landmark_map import joint_of


@dataclass(frozen=True)
class AssociationScore:
    """How well sightings were paired with landmarks."""

    method: str
    """``nn`` or ``jcbb``."""
    accuracy: float | None
    """Share of scored sightings paired right: a sighting of true landmark ``l`` is right when it went to a mapped
    landmark most of whose sightings are of ``l``; a clutter sighting is right when it went to no mapped landmark.
    None when nothing could be scored (no ids nor hidden true ids in the stream, even if it marks its clutter)."""
    landmarks_mapped: int
    """Landmarks in the estimator's final map."""
    landmarks_true: int | None
    """Distinct true landmarks among the sightings (None when the stream has no ids nor hidden true ids)."""
    sightings_scored: int
    """Sightings with a known truth (an id, a hidden true id, or marked clutter); sightings given a wrong id are not
    scored."""
    sightings_used: int
    """Sightings the estimator put on a mapped landmark."""

    def to_dict(self) -> dict:
        """The JSON object."""
        return {
            "method": self.method,
            "accuracy": self.accuracy,
            "landmarks_mapped": self.landmarks_mapped,
            "landmarks_true": self.landmarks_true,
            "sightings_scored": self.sightings_scored,
            "sightings_used": self.sightings_used,
        }


def true_labels(
    ids: Sequence[LandmarkId | None], outliers: Mapping[int, str], true_ids: Mapping[int, LandmarkId]
) -> list[LandmarkId | None | bool]:
    """Per sighting: its true landmark id, None for clutter (a sighting of nothing), False when unknown.

    Args:
        ids: The stream's landmark id of each sighting (None: none given), in step order.
        outliers: Marked sightings by number (``truth_outlier``): clutter is a sighting of nothing, a sighting
            given a wrong id or a range spike is not scored.
        true_ids: Hidden true landmarks by sighting number (``truth_landmark``), preferred to the stream's ids.
    """
    out: list[LandmarkId | None | bool] = [False if lid is None else lid for lid in ids]
    for i, lid in true_ids.items():
        if i < len(out):
            out[i] = lid
    for i, kind in outliers.items():
        if i < len(out):
            out[i] = None if kind == "clutter" else False
    return out


def majority(labels: Sequence[LandmarkId | None], truth: Sequence[LandmarkId | None | bool]) -> dict:
    """Each mapped landmark's true landmark: the true id most of its sightings carry (clutter counts as None)."""
    votes: dict[LandmarkId, Counter] = {}
    for label, true in zip(labels, truth):
        if label is not None and true is not False:
            votes.setdefault(label, Counter())[true] += 1
    return {label: counter.most_common(1)[0][0] for label, counter in votes.items()}


def score_association(
    method: str,
    labels: Sequence[LandmarkId | None],
    truth: Sequence[LandmarkId | None | bool],
    mapped: Sequence[LandmarkId],
    owner: dict | None = None,
) -> AssociationScore:
    """Score per-sighting labels (the estimator's landmark of each sighting) against the true ones.

    Args:
        method: The association method used.
        labels: Landmark id each sighting went to (None: not used), in stream order.
        truth: :func:`true_labels` of the same sightings.
        mapped: The ids of the estimator's final map.
        owner: :func:`majority` of these labels, if already computed.
    """
    if len(labels) != len(truth):
        raise ValueError(f"{len(labels)} labels for {len(truth)} sightings")
    on_map = set(mapped)
    owner = majority(labels, truth) if owner is None else owner
    scored = right = used = 0
    seen_true = set()
    for label, true in zip(labels, truth):
        mapped_label = label is not None and label in on_map
        used += mapped_label
        if true is False:
            continue
        scored += 1
        if true is None:
            right += not mapped_label
        else:
            seen_true.add(true)
            right += mapped_label and owner.get(label) == true
    if not seen_true:  # no sighting carries an id (clutter marks alone): pairing cannot be scored
        scored = right = 0
    return AssociationScore(
        method=method,
        accuracy=right / scored if scored else None,
        landmarks_mapped=len(on_map),
        landmarks_true=len(seen_true) if scored else None,
        sightings_scored=scored,
        sightings_used=used,
    )


def with_true_ids(estimate: Estimate, owner: dict) -> Estimate:
    """The estimate with each landmark renamed to its true landmark (``owner``: :func:`majority`), for landmark
    RMSE; landmarks made of clutter (or of nothing scored) left out."""
    keep = [k for k, lid in enumerate(estimate.landmark_ids) if owner.get(lid) is not None]
    return replace(
        estimate,
        landmark_ids=tuple(owner[estimate.landmark_ids[k]] for k in keep),
        landmarks=estimate.landmarks[keep],
        landmark_covs=None if estimate.landmark_covs is None else estimate.landmark_covs[keep],
        landmark_joint=None if estimate.landmark_joint is None else joint_of(estimate.landmark_joint, keep),
    )
