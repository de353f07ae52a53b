"""Profiles (docs/science.md section 2, Khoshelham and Altundag): extraction from a cloud,
wavelet de-noising, roughness-length fractal dimension and the comparison of
de-noising variants."""

from rough_viewer.profiles.comparison import Comparison, Variant, compare_denoising
from rough_viewer.profiles.extraction import Profile, extract_profile, regular_samples
from rough_viewer.profiles.fractal import RoughnessLength, roughness_length, roughness_length_2d
from rough_viewer.profiles.wavelets import (
    Denoised,
    denoise,
    denoise_result,
    noise_sigma,
    threshold_value,
)

__all__ = [
    "Comparison",
    "Denoised",
    "Profile",
    "RoughnessLength",
    "Variant",
    "compare_denoising",
    "denoise",
    "denoise_result",
    "extract_profile",
    "noise_sigma",
    "regular_samples",
    "roughness_length",
    "roughness_length_2d",
    "threshold_value",
]
