"""funcorr.match takes exactly the library's options: the keys of its table
(`funcorr::matching::MATCH_OPTIONS`, also the flags of `funcorr match`, checked by the CLI's test
`every_flag_is_the_library_option_of_its_name`) are its keywords, each documented and each
accepted, and nothing else is."""
import inspect
import re

import pytest

import funcorr
from conftest import X_PATH
from funcorr import _funcorr

# The keywords of funcorr.match that are not options of the pipeline: the shapes' preparation
# (the Laplacian options of funcorr.prepare, named as there), the segmentation of the data, the cache.
PREPARATION = {"laplacian", "cloud_neighbours", "knn", "vertex_weights", "sigma", "cache_dir"}
SEGMENTATION = {"seg_function", "threshold", "hks_time"}
# Inputs beside the shapes and the data: known corresponding points (`funcorr match --landmarks`).
INPUTS = {"landmarks"}


def documented():
    doc = funcorr.match.__doc__
    part = doc[doc.index("``options`` are") : doc.index("``progress``")]
    return set(re.findall(r"``([a-z][a-z_0-9]*)``", part)) - {"options"}


def test_the_keywords_are_the_library_options():
    keys = set(_funcorr.match_option_keys())
    assert len(keys) == len(_funcorr.match_option_keys()) > 40
    params = inspect.signature(funcorr.match).parameters
    assert [p for p in params if params[p].kind != inspect.Parameter.VAR_KEYWORD] == [
        "X",
        "Y",
        "method",
        "data",
        "progress",
    ]
    assert "method" in keys
    assert documented() == (keys - {"method"}) | SEGMENTATION | INPUTS | {"cache_dir"}


def test_every_key_is_a_keyword_and_nothing_else():
    for key in _funcorr.match_option_keys():
        try:
            _funcorr.match_basis_size("wks", {key: 7})
        except ValueError as e:
            # A value of another kind or out of range: the error names the keyword.
            assert str(e).startswith(f"{key}:"), (key, e)
        # Never TypeError (an unknown keyword).
    with pytest.raises(TypeError, match="zoomout-to"):
        funcorr.match(str(X_PATH), str(X_PATH), **{"zoomout-to": 7})
    with pytest.raises(ValueError, match="mu1: must be finite, got inf"):
        _funcorr.match_basis_size("wks", {"mu1": float("inf")})
    assert _funcorr.match_basis_size("wks", {"method": "fmap", "zoomout_to": 300}) == 300
    assert _funcorr.match_basis_size("wks", {"kprime": 130}) == 130
