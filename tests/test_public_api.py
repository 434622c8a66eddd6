"""The names ``import bagkit`` offers: each resolves (lazily), and ``dir`` lists them."""

from __future__ import annotations

import pytest

import bagkit


def test_every_public_name_resolves_and_is_listed() -> None:
    names = [name for name in bagkit.__all__ if name != "__version__"]
    assert all(getattr(bagkit, name).__module__.startswith("bagkit.") for name in names)
    assert set(bagkit.__all__) <= set(dir(bagkit))  # tab completion offers the lazy names


def test_an_unknown_name_is_an_attribute_error() -> None:
    with pytest.raises(AttributeError, match="no attribute 'read_bag'"):
        _ = bagkit.read_bag  # type: ignore[attr-defined]
