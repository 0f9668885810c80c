// Modbus round trips against the robot simulator (loopback TCP), and the simulator's
// speed against real time. Figures for docs/hal.md; not a test.
#include <benchmark/benchmark.h>

#include "robot_fixture.h"

namespace dentmark {
namespace {

void BM_StatusReadTcp(benchmark::State& state) {
  clock::MonotonicClock clock;
  auto cfg = test::sim_config();
  cfg.heartbeat_timeout = 1e6;
  auto sim = sim::robot::RobotSimulator::serve_tcp(cfg, clock);
  hal::ModbusRobot robot(test::tcp_config(sim->port()), clock);
  robot.connect();
  for (auto _ : state) benchmark::DoNotOptimize(robot.status());
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_StatusReadTcp)->UseRealTime();

void BM_CommandAndWaitTcp(benchmark::State& state) {
  // A 0.3 m move at 0.25 m/s on a clock running 'rate' times real time.
  const double rate = static_cast<double>(state.range(0));
  clock::SimClock clock(rate);
  auto cfg = test::sim_config();
  cfg.heartbeat_timeout = 1e6;
  auto sim = sim::robot::RobotSimulator::serve_tcp(cfg, clock);
  hal::ModbusRobot robot(test::tcp_config(sim->port()), clock);
  robot.connect();
  bool there = false;
  for (auto _ : state) {
    there = !there;
    robot.wait_done(robot.move_to(test::pose(0.4, there ? 0.3 : 0.0, 0.5), 0.0), 60.0, 0.01, clock);
  }
  state.counters["sim_s_per_real_s"] = rate;
}
BENCHMARK(BM_CommandAndWaitTcp)->Arg(1)->Arg(20)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(4);

}  // namespace
}  // namespace dentmark
