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


def _blob_image(contrast: float) -> np.ndarray:
    """A 61 x 61 float image: a 9 x 21 bright bar of ``contrast`` grey levels on 40."""
    image = np.full((61, 61), 40.0, dtype=np.float32)
    image[26:35, 20:41] += np.float32(contrast)
    return image


def test_contrast_normalisation_removes_a_gain():
    plain, normalised = LogFilter(size=7), LogFilter(size=7, contrast_px=2.0)
    strong, weak = _blob_image(160.0), _blob_image(80.0)
    ratio = plain.apply(strong)[26:35, 20:41] / plain.apply(weak)[26:35, 20:41]
    assert np.nanmedian(ratio) == pytest.approx(2.0, rel=1e-3)
    a, b = normalised.apply(strong), normalised.apply(weak)
    edge = np.abs(a) > 5.0
    assert edge.sum() > 40
    np.testing.assert_allclose(a[edge], b[edge], rtol=0.02)


def test_contrast_normalisation_follows_a_shading_ramp():
    """A bar lit by a ramp (twice as bright at one end): plain LoG responses along its
    outline change with the ramp, normalised ones hardly."""
    image = _blob_image(150.0)
    ramp = np.linspace(0.5, 1.0, 61, dtype=np.float32)[None, :]
    shaded = 40.0 + (image - 40.0) * ramp
    plain = LogFilter(size=7).apply(shaded)
    normalised = LogFilter(size=7, contrast_px=2.0).apply(shaded)
    left, right = (25, 22), (25, 38)  # just outside the top edge, near each end
    gain = ramp[0, 38] / ramp[0, 22]
    assert plain[right] / plain[left] == pytest.approx(gain, rel=0.02)
    assert normalised[right] / normalised[left] == pytest.approx(1.0, abs=0.02)


def test_normalised_response_has_the_stated_local_rms_and_flat_stays_flat():
    from digiteyes.templates.filtering import NORMALISED_RMS
    out = LogFilter(size=7, contrast_px=2.0).apply(_blob_image(200.0))
    band = out[22:39, 16:45]
    assert np.sqrt(np.mean(band ** 2)) == pytest.approx(NORMALISED_RMS, rel=0.5)
    assert np.abs(out[:8, :8]).max() < 1e-3
    rng = np.random.default_rng(0)
    for sigma in (0.3, 3.0):  # sensor noise of a render and of a webcam, grey levels
        noise = rng.normal(40.0, sigma, (121, 121)).astype(np.float32)
        flat = LogFilter(size=7, contrast_px=2.0).apply(noise)
        assert np.sqrt(np.mean(flat ** 2)) < 0.4 * NORMALISED_RMS
    noisy_bar = _blob_image(200.0) + rng.normal(0.0, 3.0, (61, 61)).astype(np.float32)
    edges = LogFilter(size=7, contrast_px=2.0).apply(noisy_bar)[22:39, 16:45]
    assert np.sqrt(np.mean(edges ** 2)) > 0.7 * NORMALISED_RMS


@pytest.mark.parametrize(("field", "value", "match"), [("contrast_px", -1.0, "contrast_px"),
                                                       ("contrast_floor", 0.0, "contrast_floor"),
                                                       ("contrast_noise", -1.0, "contrast_noise")])
def test_bad_contrast_options_are_refused(field, value, match):
    with pytest.raises(TemplateError, match=match):
        LogFilter(size=7, **{field: value})


def test_a_region_is_filtered_as_the_whole_image_would_be_and_the_rest_is_zero():
    rng = np.random.default_rng(1)
    image = _blob_image(150.0) + rng.normal(0.0, 0.2, (61, 61)).astype(np.float32)
    for log in (LogFilter(size=7), LogFilter(size=7, contrast_px=2.0)):
        whole = log.apply(image)
        part = log.apply(image, region=(15, 20, 45, 41))
        np.testing.assert_allclose(part[20:41, 15:45], whole[20:41, 15:45], atol=1e-4)
        assert not part[:20].any() and not part[41:].any()
        assert not part[:, :15].any() and not part[:, 45:].any()
        # a region reaching over the border is clipped to the image
        np.testing.assert_allclose(log.apply(image, region=(-10, -10, 100, 100)), whole,
                                   atol=1e-4)
    assert not LogFilter(size=7).apply(image, region=(30, 30, 30, 40)).any()
