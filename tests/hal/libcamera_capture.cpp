// libcamera capture check, libcamera test style: exit 0 pass, 1 fail, 77 skip (no
// camera on this machine; the QEMU tier's vimc provides one).
#include <cstdio>
#include <exception>

#include "dentmark/firmware/hal/camera/libcamera_camera.h"

int main() {
  try {
    const auto ids = dentmark::hal::list_libcamera_cameras();
    if (ids.empty()) {
      std::puts("skip: libcamera sees no camera");
      return 77;
    }
    dentmark::hal::LibcameraCamera cam(ids.front(), {640, 480});
    cam.start();
    double last = -1.0;
    int frames = 0;
    for (int i = 0; i < 20 && frames < 5; ++i) {
      const auto f = cam.grab(2.0);
      if (!f) continue;
      if (f->image.cols != 640 || f->image.rows != 480 || !(f->time > last)) {
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
    std::printf("pass: %d frames from %s\n", frames, ids.front().c_str());
    return 0;
  } catch (const std::exception& e) {
    std::printf("fail: %s\n", e.what());
    return 1;
  }
}
