#include "dentmark/firmware/hal/camera/libcamera_camera.h"

#include <libcamera/libcamera.h>
#include <linux/videodev2.h>
#include <sys/mman.h>

#include <chrono>

#include "dentmark/firmware/hal/camera/v4l2_camera.h"

namespace dentmark::hal {
namespace {

// libcamera pixel formats whose plane 0 we can read as luma, with the V4L2 name of that layout.
// libcamera names packed RGB by DRM fourcc, least significant byte last: RGB888 is
// B, G, R in memory (V4L2 BGR24), BGR888 is R, G, B (V4L2 RGB24).
std::uint32_t luma_layout(const libcamera::PixelFormat& f) {
  if (f == libcamera::formats::R8) return V4L2_PIX_FMT_GREY;
  if (f == libcamera::formats::YUYV) return V4L2_PIX_FMT_YUYV;
  if (f == libcamera::formats::UYVY) return V4L2_PIX_FMT_UYVY;
  if (f == libcamera::formats::NV12) return V4L2_PIX_FMT_NV12;
  if (f == libcamera::formats::NV21) return V4L2_PIX_FMT_NV21;
  if (f == libcamera::formats::RGB888) return V4L2_PIX_FMT_BGR24;
  if (f == libcamera::formats::BGR888) return V4L2_PIX_FMT_RGB24;
  return 0;
}

}  // namespace

std::vector<std::string> list_libcamera_cameras() {
  libcamera::CameraManager manager;
  if (manager.start() != 0) return {};
  std::vector<std::string> ids;
  for (const auto& c : manager.cameras()) ids.push_back(c->id());
  manager.stop();
  return ids;
}

LibcameraCamera::LibcameraCamera(std::string id, cv::Size size, unsigned buffers)
    : id_(std::move(id)), size_(size), want_buffers_(std::max(4u, buffers)) {}

LibcameraCamera::~LibcameraCamera() {
  stop();
}

void LibcameraCamera::start() {
  if (running_) return;
  try {
    manager_ = std::make_unique<libcamera::CameraManager>();
    if (manager_->start() != 0) throw CameraError("libcamera: camera manager did not start");
    const auto cams = manager_->cameras();
    camera_ = id_.empty() ? (cams.empty() ? nullptr : cams.front()) : manager_->get(id_);
    if (!camera_)
      throw CameraError("libcamera: no camera '" + id_ + "' (" + std::to_string(cams.size()) +
                        " cameras found)");
    if (id_.empty()) id_ = camera_->id();
    if (camera_->acquire() != 0) throw CameraError("libcamera " + id_ + ": camera busy (acquire failed)");
    acquired_ = true;

    auto config = camera_->generateConfiguration({libcamera::StreamRole::VideoRecording});
    if (!config || config->empty()) throw CameraError("libcamera " + id_ + ": no configuration for video");
    libcamera::StreamConfiguration& sc = config->at(0);
    sc.size = libcamera::Size(static_cast<unsigned>(size_.width), static_cast<unsigned>(size_.height));
    sc.bufferCount = want_buffers_;
    // Ask for formats with a luma plane, best first, then packed RGB (converted to luma;
    // vimc's pipeline gives only that); keep the first the pipeline accepts unchanged.
    const libcamera::PixelFormat wanted[] = {libcamera::formats::R8,    libcamera::formats::NV12,
                                             libcamera::formats::YUYV,  libcamera::formats::NV21,
                                             libcamera::formats::UYVY,  libcamera::formats::RGB888,
                                             libcamera::formats::BGR888};
    bool ok = false;
    for (const auto& f : wanted) {
      sc.pixelFormat = f;
      sc.size = libcamera::Size(static_cast<unsigned>(size_.width), static_cast<unsigned>(size_.height));
      if (config->validate() == libcamera::CameraConfiguration::Invalid) continue;
      if (luma_layout(sc.pixelFormat) != 0) {
        ok = true;
        break;
      }
    }
    if (!ok) throw CameraError("libcamera " + id_ + ": no stream format with a readable luma plane");
    // Read back what validate() settled on.
    if (sc.size.width != static_cast<unsigned>(size_.width) ||
        sc.size.height != static_cast<unsigned>(size_.height))
      throw CameraError("libcamera " + id_ + ": asked " + std::to_string(size_.width) + "x" +
                        std::to_string(size_.height) + ", the pipeline gives " + sc.size.toString());
    if (sc.bufferCount < 4)
      throw CameraError("libcamera " + id_ + ": " + std::to_string(sc.bufferCount) +
                        " buffers, need at least 4");
    if (camera_->configure(config.get()) != 0) throw CameraError("libcamera " + id_ + ": configure failed");
    fourcc_ = luma_layout(sc.pixelFormat);
    stride_ = sc.stride;
    stream_ = sc.stream();

    allocator_ = std::make_unique<libcamera::FrameBufferAllocator>(camera_);
    if (allocator_->allocate(stream_) < 4)
      throw CameraError("libcamera " + id_ + ": buffer allocation failed");
    const auto& buffers = allocator_->buffers(stream_);
    for (std::size_t i = 0; i < buffers.size(); ++i) {
      const auto& plane = buffers[i]->planes()[0];
      // Map from the start of the dmabuf: plane offsets need not be page aligned.
      const std::size_t length = static_cast<std::size_t>(plane.offset) + plane.length;
      void* base = ::mmap(nullptr, length, PROT_READ, MAP_SHARED, plane.fd.get(), 0);
      if (base == MAP_FAILED) throw CameraError("libcamera " + id_ + ": mmap of a frame buffer failed");
      mappings_.push_back({base, length, plane.offset});
      auto request = camera_->createRequest(i);
      if (!request || request->addBuffer(stream_, buffers[i].get()) != 0)
        throw CameraError("libcamera " + id_ + ": cannot create a request");
      requests_.push_back(std::move(request));
    }
    camera_->requestCompleted.connect(this, &LibcameraCamera::on_request_completed);
    if (camera_->start() != 0) throw CameraError("libcamera " + id_ + ": start failed");
    running_ = true;
    for (auto& r : requests_)
      if (camera_->queueRequest(r.get()) != 0)
        throw CameraError("libcamera " + id_ + ": queueRequest failed");
  } catch (...) {
    stop();
    throw;
  }
}

void LibcameraCamera::on_request_completed(libcamera::Request* request) {
  // libcamera's thread: hand over and return at once.
  if (request->status() == libcamera::Request::RequestCancelled) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    completed_.push_back(request);
  }
  completed_cv_.notify_one();
}

std::optional<Frame> LibcameraCamera::grab(double timeout) {
  if (!running_) throw CameraError("libcamera " + id_ + ": grab before start");
  libcamera::Request* request = nullptr;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    if (!completed_cv_.wait_for(lock, std::chrono::duration<double>(std::max(0.0, timeout)),
                                [&] { return !completed_.empty(); }))
      return std::nullopt;
    request = completed_.front();
    completed_.pop_front();
  }
  libcamera::FrameBuffer* buffer = request->findBuffer(stream_);
  const libcamera::FrameMetadata& md = buffer->metadata();
  std::optional<Frame> out;
  if (md.status == libcamera::FrameMetadata::FrameSuccess) {
    const Mapping& m = mappings_.at(request->cookie());
    const auto* data = static_cast<const std::uint8_t*>(m.base) + m.offset;
    Frame f;
    f.image = luma_from_buffer(data, md.planes()[0].bytesused, fourcc_, size_.width, size_.height, stride_);
    f.time = static_cast<double>(md.timestamp) * 1e-9;  // sensor timestamp, CLOCK_BOOTTIME/MONOTONIC ns
    f.sequence = md.sequence;
    out = std::move(f);
  }
  request->reuse(libcamera::Request::ReuseBuffers);
  camera_->queueRequest(request);
  return out;
}

void LibcameraCamera::stop() {
  if (camera_) {
    if (running_) {
      camera_->stop();  // completes every pending request as cancelled
      running_ = false;
    }
    camera_->requestCompleted.disconnect(this, &LibcameraCamera::on_request_completed);
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    completed_.clear();
  }
  requests_.clear();
  for (auto& m : mappings_) ::munmap(m.base, m.length);
  mappings_.clear();
  if (allocator_ && stream_) allocator_->free(stream_);
  allocator_.reset();
  stream_ = nullptr;
  if (camera_ && acquired_) camera_->release();
  acquired_ = false;
  camera_.reset();
  if (manager_) manager_->stop();
  manager_.reset();
}

}  // namespace dentmark::hal
