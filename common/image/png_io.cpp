#include "dentmark/common/image/png_io.h"

#include <png.h>

#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <memory>
#include <vector>

namespace dentmark::image {
namespace {

// libpng reports errors by longjmp. The functions that call setjmp below hold only
// plain data, so jumping out of libpng skips no destructor; C++ objects live in
// their callers.
struct ErrorSink {
  char message[256] = "";
};

extern "C" void on_png_error(png_structp png, png_const_charp msg) {
  auto* sink = static_cast<ErrorSink*>(png_get_error_ptr(png));
  std::snprintf(sink->message, sizeof sink->message, "%s", msg);
  png_longjmp(png, 1);
}

extern "C" void on_png_warning(png_structp, png_const_charp) {}

struct Header {
  png_uint_32 width = 0, height = 0;
  int channels = 0, bit_depth = 0;
};

using File = std::unique_ptr<std::FILE, int (*)(std::FILE*)>;

File open_file(const std::string& path, const char* mode) {
  std::FILE* f = std::fopen(path.c_str(), mode);
  if (!f) throw ImageError(path + ": cannot open: " + std::strerror(errno));
  return {f, &std::fclose};
}

// Reads the header and sets the transformations: to 8/16-bit grey or BGR in native
// order, or (grey8) to 8-bit grey.
bool read_header(png_structp png, png_infop info, std::FILE* f, bool grey8, Header* h) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_init_io(png, f);
  png_read_info(png, info);
  const int colour = png_get_color_type(png, info);
  if (colour == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (colour == PNG_COLOR_TYPE_GRAY && png_get_bit_depth(png, info) < 8) png_set_expand_gray_1_2_4_to_8(png);
  png_set_strip_alpha(png);
  if (grey8) {
    if (png_get_bit_depth(png, info) == 16) png_set_strip_16(png);
    if (colour & PNG_COLOR_MASK_COLOR) png_set_rgb_to_gray(png, 1, 0.299, 0.587);
  }
  png_set_bgr(png);
  if (png_get_bit_depth(png, info) == 16 && !grey8) png_set_swap(png);  // PNG is big-endian
  png_read_update_info(png, info);
  h->width = png_get_image_width(png, info);
  h->height = png_get_image_height(png, info);
  h->channels = png_get_channels(png, info);
  h->bit_depth = png_get_bit_depth(png, info);
  return true;
}

bool read_rows(png_structp png, png_infop info, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_image(png, rows);
  png_read_end(png, info);
  return true;
}

bool write_all(png_structp png, png_infop info, std::FILE* f, const Header* h, png_bytepp rows,
               int compression) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_init_io(png, f);
  png_set_compression_level(png, compression);
  png_set_IHDR(png, info, h->width, h->height, h->bit_depth,
               h->channels == 1 ? PNG_COLOR_TYPE_GRAY : PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  if (h->channels == 3) png_set_bgr(png);
  if (h->bit_depth == 16) png_set_swap(png);
  png_write_image(png, rows);
  png_write_end(png, info);
  return true;
}

cv::Mat read_png_as(const std::string& path, bool grey8) {
  File f = open_file(path, "rb");
  png_byte signature[8];
  if (std::fread(signature, 1, sizeof signature, f.get()) != sizeof signature ||
      png_sig_cmp(signature, 0, sizeof signature) != 0)
    throw ImageError(path + ": not a PNG file");
  ErrorSink sink;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &sink, on_png_error, on_png_warning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!info) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    throw ImageError(path + ": out of memory");
  }
  png_set_sig_bytes(png, sizeof signature);
  struct Destroy {
    png_structp* png;
    png_infop* info;
    ~Destroy() { png_destroy_read_struct(png, info, nullptr); }
  } destroy{&png, &info};

  Header h;
  if (!read_header(png, info, f.get(), grey8, &h)) throw ImageError(path + ": " + sink.message);
  if (h.channels != 1 && h.channels != 3) throw ImageError(path + ": unsupported PNG channel layout");
  if (h.width == 0 || h.height == 0 || h.width > 65535 || h.height > 65535)
    throw ImageError(path + ": image size " + std::to_string(h.width) + " x " + std::to_string(h.height) +
                     " out of range");
  const int depth = h.bit_depth == 16 ? CV_16U : CV_8U;
  cv::Mat img(static_cast<int>(h.height), static_cast<int>(h.width), CV_MAKETYPE(depth, h.channels));
  std::vector<png_bytep> rows(h.height);
  for (png_uint_32 r = 0; r < h.height; ++r) rows[r] = img.ptr<png_byte>(static_cast<int>(r));
  if (!read_rows(png, info, rows.data())) throw ImageError(path + ": " + sink.message);
  return img;
}

}  // namespace

cv::Mat read_png(const std::string& path) {
  return read_png_as(path, false);
}

cv::Mat read_png_grey(const std::string& path) {
  return read_png_as(path, true);
}

void write_png(const std::string& path, const cv::Mat& image, int compression) {
  const int depth = image.depth(), channels = image.channels();
  if ((depth != CV_8U && depth != CV_16U) || (channels != 1 && channels != 3) || image.empty())
    throw ImageError(path + ": only 8- or 16-bit grey or BGR images are written as PNG");
  File f = open_file(path, "wb");
  ErrorSink sink;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &sink, on_png_error, on_png_warning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    throw ImageError(path + ": out of memory");
  }
  struct Destroy {
    png_structp* png;
    png_infop* info;
    ~Destroy() { png_destroy_write_struct(png, info); }
  } destroy{&png, &info};
  Header h;
  h.width = static_cast<png_uint_32>(image.cols);
  h.height = static_cast<png_uint_32>(image.rows);
  h.channels = channels;
  h.bit_depth = depth == CV_16U ? 16 : 8;
  std::vector<png_bytep> rows(h.height);
  for (int r = 0; r < image.rows; ++r)
    rows[static_cast<std::size_t>(r)] = const_cast<png_bytep>(image.ptr<png_byte>(r));
  if (!write_all(png, info, f.get(), &h, rows.data(), compression))
    throw ImageError(path + ": " + sink.message);
  if (std::fflush(f.get()) != 0 || std::ferror(f.get()))
    throw ImageError(path + ": cannot write: " + std::strerror(errno));
}

}  // namespace dentmark::image
