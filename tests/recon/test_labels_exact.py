"""Which scene folders ``aerostereo-recon labels`` refuses: those whose labels are exact (the demo world's,
by its generator's labels method), never a twin the labeller itself labelled."""

from __future__ import annotations

import pytest

from cliutil.errors import BadInput
from recon.semantics.labels import EXACT_LABELS, LabelOptions, refuse_exact_labels
from sim.worlds.demo import LABELS_METHOD


def test_the_demo_worlds_labels_are_exact_and_the_labellers_are_not():
    assert LABELS_METHOD.startswith(EXACT_LABELS)
    assert not LabelOptions().method().startswith(EXACT_LABELS)


def test_exact_labels_are_refused_naming_the_folder(tmp_path):
    with pytest.raises(BadInput, match=f"{tmp_path}: its labels \\(labels.npz\\) are exact"):
        refuse_exact_labels(tmp_path, {"labels": {"file": "labels.npz", "method": LABELS_METHOD}})


@pytest.mark.parametrize("meta", [{}, {"labels": None}, {"labels": "broken"}, {"labels": {"method": 3}},
                                  {"labels": {"method": LabelOptions().method()}}])
def test_estimated_missing_or_broken_labels_may_be_relabelled(tmp_path, meta):
    refuse_exact_labels(tmp_path, meta)  # no exception
