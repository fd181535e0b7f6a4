"""The LoG filter: zero mean, sign, size option and errors."""

import numpy as np
import pytest

from digiteyes.templates.filtering import LogFilter, TemplateError


def test_kernel_is_zero_mean_and_sized():
    for size in (7, 13):
        kernel = LogFilter(size=size).kernel
        assert kernel.shape == (size, size)
        assert abs(float(kernel.sum())) < 1e-5 * float(np.abs(kernel).sum())


def test_bright_blob_gives_positive_centre_and_flat_image_zero():
    image = np.full((41, 41), 50, dtype=np.uint8)
    assert np.abs(LogFilter().apply(image)).max() < 1e-3
    image[18:23, 18:23] = 200
    out = LogFilter().apply(image)
    assert out[20, 20] > 10.0
    assert out[20, 20] == out.max()


def test_size_zero_passes_grey_through():
    image = np.arange(12, dtype=np.uint8).reshape(3, 4)
    np.testing.assert_array_equal(LogFilter(size=0).apply(image), image.astype(np.float32))


@pytest.mark.parametrize("size", [4, 1, -3])
def test_bad_size_is_refused(size):
    with pytest.raises(TemplateError, match="odd integer"):
        LogFilter(size=size)
