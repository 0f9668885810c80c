// libcamera capture check, libcamera test style: exit 0 pass, 1 fail, 77 skip (no
// camera on this machine; the QEMU tier's vimc provides one).
#include <cstdio>
#include <exception>

#include "dentmark/firmware/hal/camera/libcamera_camera.h"

// Usage: libcamera_capture [WIDTHxHEIGHT]   (default 640x480; frames must have that size)
int main(int argc, char** argv) {
  int width = 640, height = 480;
  if (argc > 1 && std::sscanf(argv[1], "%dx%d", &width, &height) != 2) {
    std::printf("fail: size '%s' is not WIDTHxHEIGHT\n", argv[1]);
    return 2;
  }
  try {
    const auto ids = dentmark::hal::list_libcamera_cameras();
    if (ids.empty()) {
      std::puts("skip: libcamera sees no camera");
      return 77;
    }
    dentmark::hal::LibcameraCamera cam(ids.front(), {width, height});
    cam.start();
    double last = -1.0;
    int frames = 0;
    for (int i = 0; i < 20 && frames < 5; ++i) {
      const auto f = cam.grab(2.0);
      if (!f) continue;
      if (f->image.cols != width || f->image.rows != height || !(f->time > last)) {
        std::puts("fail: wrong frame size or non-increasing time");
        return 1;
      }
      last = f->time;
      ++frames;
    }
    cam.stop();
    if (frames < 5) {
      std::puts("fail: fewer than 5 frames in 20 waits of 2 s");
      return 1;
    }
    std::printf("pass: %d frames of %dx%d from %s\n", frames, width, height, ids.front().c_str());
    return 0;
  } catch (const std::exception& e) {
    std::printf("fail: %s\n", e.what());
    return 1;
  }
}
