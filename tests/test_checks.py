import math

import numpy as np
import pytest

from dancekit._checks import check_fps
from dancekit.errors import ParameterError


@pytest.mark.parametrize("fps", [25, 25.0, np.float32(25), np.int64(25), np.array(25.0)])
def test_check_fps_accepts_numbers(fps):
    assert check_fps(fps) == 25.0
    assert isinstance(check_fps(fps), float)


@pytest.mark.parametrize("fps", [0, -1, math.nan, math.inf, True, "25", None, [25], np.array([25.0, 30.0])])
def test_check_fps_refuses(fps):
    with pytest.raises(ParameterError, match="fps must be a positive number"):
        check_fps(fps)


def test_check_fps_names_the_argument():
    with pytest.raises(ParameterError, match="target_fps must be"):
        check_fps(0, name="target_fps")
