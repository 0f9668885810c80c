#pragma once
// Reading and writing the fields of the calibration files (OpenCV FileStorage YAML):
// every refusal is a CalibrateError naming the file and the field.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "dentmark/common/geometry/transform.h"

namespace dentmark::calibrate {

// Opens a YAML file (files::open_yaml); refuses a missing or unreadable one with a
// CalibrateError.
cv::FileStorage open_yaml(const std::filesystem::path& path);
// A rows×cols matrix (rows 0: any number of rows) of finite values, as doubles.
cv::Mat read_matrix(const cv::FileNode& node, const std::string& file, const std::string& name, int rows,
                    int cols);
// A 4×4 rigid transform [R t; 0 0 0 1] (R orthonormal within 1e-3, det +1), re-orthonormalised.
Transform read_transform(const cv::FileNode& node, const std::string& file, const std::string& name);
// An N×3 matrix of points, metres.
std::vector<Eigen::Vector3d> read_points(const cv::FileNode& node, const std::string& file,
                                         const std::string& name);
// A residual in metres: present, a finite number ≥ 0, and at most 'limit'.
void check_residual(const cv::FileStorage& fs, const std::string& file, const char* name, double limit);

cv::Mat matrix_of(const Transform& t);
nlohmann::json json_of(const Transform& t);

}  // namespace dentmark::calibrate
