#include "dentmark/common/image/jpeg_io.h"

// jpeglib.h needs FILE and size_t declared first.
#include <cstddef>
#include <cstdio>
// clang-format off
#include <jpeglib.h>
// clang-format on

#include <cerrno>
#include <csetjmp>
#include <cstring>
#include <memory>

namespace dentmark::image {
namespace {

// libjpeg reports errors through error_exit, which must not return: it longjmps back
// to read_all, whose frame holds only plain data (no destructor is skipped).
struct ErrorSink {
  jpeg_error_mgr mgr;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX] = "";
  char warning[JMSG_LENGTH_MAX] = "";  // the first warning: libjpeg's word for damaged data
};

extern "C" void on_jpeg_error(j_common_ptr cinfo) {
  auto* sink = reinterpret_cast<ErrorSink*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, sink->message);
  std::longjmp(sink->jump, 1);
}

// Level -1 is a warning: damaged or truncated data that libjpeg decodes anyway (a
// truncated file comes out grey below the cut). Kept, and refused after decoding.
extern "C" void on_jpeg_message(j_common_ptr cinfo, int level) {
  auto* sink = reinterpret_cast<ErrorSink*>(cinfo->err);
  if (level == -1 && cinfo->err->num_warnings++ == 0) (*cinfo->err->format_message)(cinfo, sink->warning);
}

// Decodes into 'out' (allocated once the size is known). False with sink->message set
// on a decoding error.
bool read_all(jpeg_decompress_struct* cinfo, ErrorSink* sink, std::FILE* f, cv::Mat* out) {
  if (setjmp(sink->jump)) return false;
  jpeg_stdio_src(cinfo, f);
  jpeg_read_header(cinfo, TRUE);
  cinfo->out_color_space = JCS_GRAYSCALE;
  jpeg_start_decompress(cinfo);
  if (cinfo->output_components != 1) {
    std::snprintf(sink->message, sizeof sink->message, "%d components after conversion to grey",
                  cinfo->output_components);
    return false;
  }
  out->create(static_cast<int>(cinfo->output_height), static_cast<int>(cinfo->output_width), CV_8UC1);
  while (cinfo->output_scanline < cinfo->output_height) {
    JSAMPROW row = out->ptr<JSAMPLE>(static_cast<int>(cinfo->output_scanline));
    jpeg_read_scanlines(cinfo, &row, 1);
  }
  jpeg_finish_decompress(cinfo);
  return true;
}

}  // namespace

cv::Mat read_jpeg_grey(const std::string& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw ImageError(path + ": cannot open: " + std::strerror(errno));
  jpeg_decompress_struct cinfo{};
  ErrorSink sink{};
  cinfo.err = jpeg_std_error(&sink.mgr);
  sink.mgr.error_exit = on_jpeg_error;
  sink.mgr.emit_message = on_jpeg_message;
  jpeg_create_decompress(&cinfo);
  struct Destroy {
    jpeg_decompress_struct* cinfo;
    ~Destroy() { jpeg_destroy_decompress(cinfo); }
  } destroy{&cinfo};
  cv::Mat img;
  if (!read_all(&cinfo, &sink, f.get(), &img))
    throw ImageError(path + ": not a readable JPEG: " + sink.message);
  if (sink.mgr.num_warnings > 0) throw ImageError(path + ": damaged JPEG: " + sink.warning);
  return img;
}

}  // namespace dentmark::image
