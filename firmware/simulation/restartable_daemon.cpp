#include "dentmark/firmware/simulation/restartable_daemon.h"

#include "dentmark/common/log.h"

namespace dentmark::simulation {
namespace fs = std::filesystem;

namespace {

// What a restarted daemon finds on disk: 'dir' as it was at the kill.
struct DiskAtKill {
  explicit DiskAtKill(fs::path state_dir) : dir(std::move(state_dir)), copy(dir.string() + ".at-kill") {
    fs::remove_all(copy);
    if (fs::exists(dir)) fs::copy(dir, copy, fs::copy_options::recursive);
  }
  void restore() const {
    fs::remove_all(dir);
    if (fs::exists(copy)) fs::rename(copy, dir);
  }
  fs::path dir, copy;
};

}  // namespace

RestartableDaemon::RestartableDaemon(std::function<daemon::DaemonOptions(int)> make_options,
                                     clock::Clock& clock, hal::SimGpio& chip,
                                     sim::robot::RobotSimulator& robot, std::function<void()> on_restart)
    : make_options_(std::move(make_options)),
      on_restart_(std::move(on_restart)),
      clock_(clock),
      chip_(chip),
      robot_(robot) {
  start_daemon();
}

RestartableDaemon::~RestartableDaemon() {
  stop();
}

void RestartableDaemon::start_daemon() {
  daemon::DaemonOptions options = make_options_(generation_.load());
  if (port_.load() != 0) options.port = port_.load();
  auto edge = std::make_shared<daemon::EdgeDaemon>(std::move(options), clock_);
  edge->start();
  port_ = edge->port();
  std::lock_guard lock(mutex_);
  daemon_ = std::move(edge);
}

std::shared_ptr<daemon::EdgeDaemon> RestartableDaemon::current() const {
  std::lock_guard lock(mutex_);
  return daemon_;
}

long RestartableDaemon::pairs_captured() const {
  std::lock_guard lock(mutex_);
  const station::CameraTracking* cameras = daemon_ ? daemon_->cameras() : nullptr;
  return pairs_before_ + (cameras ? cameras->pairs_captured() : 0);
}

void RestartableDaemon::kill() {
  std::shared_ptr<daemon::EdgeDaemon> dead;
  {
    std::lock_guard lock(mutex_);
    dead = std::move(daemon_);
  }
  if (!dead) return;
  ++generation_;  // its callbacks no longer act on the twin
  killed_at_ = clock_.now();
  const DiskAtKill disk(dead->state_dir());
  chip_.release_all();
  robot_.inject_drop(1 << 30);  // whatever its threads still send never reaches the robot
  log::warn("twin: daemon killed at t = " + std::to_string(clock_.now()) + " s");
  // Its threads end; what they do meanwhile is cut off above, or undone below.
  dead->stop();
  if (dead->cameras()) {
    std::lock_guard lock(mutex_);
    pairs_before_ += dead->cameras()->pairs_captured();
  }
  dead.reset();
  disk.restore();
}

void RestartableDaemon::restart(double after) {
  clock_.sleep_until(killed_at_ + after);
  robot_.inject_drop(0);
  log::info("twin: daemon restarted at t = " + std::to_string(clock_.now()) + " s");
  start_daemon();
  if (on_restart_) on_restart_();
}

void RestartableDaemon::stop() {
  if (const auto edge = current()) edge->stop();
}

}  // namespace dentmark::simulation
