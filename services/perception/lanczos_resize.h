// Image resizing that gives the same bytes as PIL's Image.resize with
// LANCZOS (alias ANTIALIAS) on 8-bit RGB, which is how SPANet's own
// preprocessing shrinks and enlarges crops. OpenCV's INTER_LANCZOS4 is a
// different filter (a fixed 8-tap kernel that does not widen when
// shrinking), so features computed from it would differ from the ones the
// network was trained on.
//
// The method: a separable Lanczos-3 filter whose support widens by the
// scale factor when shrinking, weights normalised to sum one and rounded to
// 22-bit fixed point, a horizontal pass then a vertical pass, each rounding
// and clamping to 8 bits. Pure function; thread-safe.
#ifndef BITEWISE_SERVICES_PERCEPTION_LANCZOS_RESIZE_H_
#define BITEWISE_SERVICES_PERCEPTION_LANCZOS_RESIZE_H_

#include "opencv2/core.hpp"

namespace bitewise::perception {

// Resizes a CV_8UC3 (or CV_8UC1) image to `size` (both sides >= 1).
// Returns an image of the same type; a copy when the size is unchanged.
cv::Mat ResizeLanczosAsPil(const cv::Mat& src, cv::Size size);

}  // namespace bitewise::perception

#endif  // BITEWISE_SERVICES_PERCEPTION_LANCZOS_RESIZE_H_
