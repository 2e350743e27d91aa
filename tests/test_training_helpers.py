"""Shared training plumbing: the visible-subset gather/scatter."""

from __future__ import annotations

import torch

from olatbench.methods.training import VisibleSubset


def test_visible_subset_picks_and_scatters_the_seen_rows() -> None:
    radii = torch.tensor([3, 0, 2, 0, 1])
    values = torch.arange(10.0).reshape(5, 2)
    subset = VisibleSubset(radii)
    assert not subset.everything
    torch.testing.assert_close(subset.pick(values), values[[0, 2, 4]])
    scattered = subset.scatter(subset.pick(values) + 100.0)
    expected = torch.zeros(5, 2)
    expected[[0, 2, 4]] = values[[0, 2, 4]] + 100.0
    torch.testing.assert_close(scattered, expected)


def test_visible_subset_is_the_identity_when_everything_is_seen() -> None:
    values = torch.randn(4, 3, requires_grad=True)
    subset = VisibleSubset(torch.tensor([1, 2, 3, 4]))
    assert subset.everything and subset.pick(values) is values and subset.scatter(values) is values
    subset.scatter(subset.pick(values) * 2.0).sum().backward()
    torch.testing.assert_close(values.grad, torch.full((4, 3), 2.0))
