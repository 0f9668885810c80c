#pragma once
// An independent renderer of a planar target seen by a stereo pair with known K, R, T
// (no lens distortion): the target's texture is warped by the plane-to-image
// homography H = K [r1 r2 t] of each camera, supersampled 4x and box-filtered (so
// corners sit at their true sub-pixel positions), then blurred and given Gaussian
// noise. Shares no code with the library under test.

#include <opencv2/core.hpp>

namespace dentmark::calibrate::test {

struct RenderedCamera {
  cv::Matx33d K;
};

struct RenderSettings {
  cv::Size size{640, 480};
  double blur_sigma_px = 0.7;  // optics
  double noise_sigma = 2.0;    // grey levels, on black 40 / white 215
  int supersample = 4;
};

// The target's texture: 'px_per_square' pixels per square, its first inner corner
// (board point (0, 0)) at texture coordinate (origin_px, origin_px) in OpenCV's
// pixel-centre convention. texture_from_board maps board metres to texture pixels.
struct Texture {
  cv::Mat image;  // 8-bit grey
  cv::Matx33d texture_from_board;
};

// A chessboard with cols × rows inner corners and one white square of margin.
Texture chessboard_texture(int cols, int rows, double square_m, int px_per_square = 64);

// The image of the texture seen by a camera with intrinsics K at pose T_cam_board
// (R_cam_board, t_cam_board), with blur and noise from 'rng'.
cv::Mat render_view(const Texture& tex, const cv::Matx33d& K, const cv::Matx33d& R_cam_board,
                    const cv::Vec3d& t_cam_board, const RenderSettings& s, cv::RNG& rng);

}  // namespace dentmark::calibrate::test
