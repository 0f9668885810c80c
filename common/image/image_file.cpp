#include "dentmark/common/image/image_file.h"

#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>

#include "dentmark/common/image/jpeg_io.h"

namespace dentmark::image {

cv::Mat read_grey_image(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ImageError(path + ": cannot open: " + std::strerror(errno));
  std::array<unsigned char, 8> head{};
  in.read(reinterpret_cast<char*>(head.data()), head.size());
  const auto got = static_cast<std::size_t>(in.gcount());
  constexpr std::array<unsigned char, 8> kPng{0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (got == kPng.size() && head == kPng) return read_png_grey(path);
  if (got >= 3 && head[0] == 0xff && head[1] == 0xd8 && head[2] == 0xff) return read_jpeg_grey(path);
  throw ImageError(path + ": neither a PNG nor a JPEG file (by its first bytes)");
}

}  // namespace dentmark::image
