#include "dentmark/host/update/box_update.h"

#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "dentmark/common/process.h"

namespace dentmark::update {

std::optional<RaucSlot> RaucStatus::booted() const {
  for (const RaucSlot& s : slots)
    if (s.state == "booted") return s;
  return std::nullopt;
}

namespace {

std::string text_field(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.contains(key)) throw UpdateError("rauc status: " + where + ": no field '" + key + "'");
  const nlohmann::json& v = j.at(key);
  if (v.is_null()) return {};
  if (!v.is_string()) throw UpdateError("rauc status: " + where + ": field '" + key + "' is not a string");
  return v.get<std::string>();
}

}  // namespace

RaucStatus parse_rauc_status(const std::string& json) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(json);
  } catch (const nlohmann::json::exception& e) {
    throw UpdateError(std::string("rauc status: not JSON (") + e.what() + ")");
  }
  if (!j.is_object()) throw UpdateError("rauc status: not a JSON object");
  RaucStatus s;
  s.compatible = text_field(j, "compatible", "top level");
  s.boot_primary = text_field(j, "boot_primary", "top level");
  if (!j.contains("slots") || !j.at("slots").is_array()) throw UpdateError("rauc status: no 'slots' array");
  // RAUC lists each slot as a one-entry object {"rootfs.0": {...}}.
  for (const nlohmann::json& entry : j.at("slots")) {
    if (!entry.is_object()) throw UpdateError("rauc status: a slot entry is not an object");
    for (const auto& [name, slot] : entry.items()) {
      if (!slot.is_object()) throw UpdateError("rauc status: slot " + name + " is not an object");
      s.slots.push_back(
          {name, text_field(slot, "bootname", "slot " + name), text_field(slot, "state", "slot " + name),
           slot.contains("boot_status") ? text_field(slot, "boot_status", "slot " + name) : ""});
    }
  }
  return s;
}

Verdict judge(const RaucStatus& after, const std::string& old_slot, const std::string& new_slot,
              const std::vector<std::string>& unit_states) {
  const std::optional<RaucSlot> booted = after.booted();
  if (!booted) return Verdict::kWaiting;
  if (booted->name == old_slot) return Verdict::kRolledBack;
  if (booted->name != new_slot) return Verdict::kWaiting;
  bool all_active = !unit_states.empty();
  for (const std::string& state : unit_states) {
    if (state == "failed") return Verdict::kNewSlotBad;
    all_active = all_active && state == "active";
  }
  return all_active && booted->boot_status == "good" ? Verdict::kUpdated : Verdict::kWaiting;
}

namespace {

class Box {
 public:
  explicit Box(const BoxAddress& address) : address_(address) {}

  process::Result ssh(const std::string& command, double timeout) const {
    std::vector<std::string> argv{"ssh", "-p", std::to_string(address_.ssh_port)};
    add_common(argv);
    argv.push_back(address_.destination);
    argv.push_back(command);
    return process::run(argv, timeout);
  }
  // The command's output; throws naming 'what' when ssh or the command failed.
  std::string ssh_checked(const std::string& command, const std::string& what, double timeout) const {
    const process::Result r = ssh(command, timeout);
    if (r.timed_out)
      throw UpdateError(what + ": no answer from " + address_.destination + " within " +
                        std::to_string(static_cast<int>(timeout)) + " s");
    if (r.exit_code != 0)
      throw UpdateError(what + " failed (exit " + std::to_string(r.exit_code) + "): " + last_lines(r.output));
    return r.output;
  }
  void copy(const std::string& local, const std::string& remote) const {
    std::vector<std::string> argv{"scp", "-q", "-P", std::to_string(address_.ssh_port)};
    add_common(argv);
    argv.push_back(local);
    argv.push_back(address_.destination + ":" + remote);
    const process::Result r = process::run(argv, 1800.0);
    if (r.exit_code != 0 || r.timed_out)
      throw UpdateError("copying " + local + " to " + address_.destination + ":" + remote +
                        " failed: " + last_lines(r.output));
  }
  static std::string last_lines(const std::string& output, int n = 4) {
    std::vector<std::string> lines;
    std::istringstream in(output);
    for (std::string line; std::getline(in, line);)
      if (!line.empty()) lines.push_back(line);
    std::string out;
    for (std::size_t i = lines.size() > static_cast<std::size_t>(n) ? lines.size() - n : 0; i < lines.size();
         ++i)
      out += (out.empty() ? "" : " | ") + lines[i];
    return out.empty() ? "(no output)" : out;
  }

 private:
  void add_common(std::vector<std::string>& argv) const {
    if (!address_.identity.empty()) argv.insert(argv.end(), {"-i", address_.identity});
    // Never a password prompt; a box that stops answering ends the call.
    for (const char* o :
         {"BatchMode=yes", "ConnectTimeout=10", "ServerAliveInterval=5", "ServerAliveCountMax=3"})
      argv.insert(argv.end(), {"-o", o});
    for (const std::string& o : address_.ssh_options) argv.insert(argv.end(), {"-o", o});
  }
  BoxAddress address_;
};

std::string quoted(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::vector<std::string> words(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string w; in >> w;) out.push_back(w);
  return out;
}

std::string joined(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : " ") + item;
  return out;
}

// The box's RAUC pre-install handler (packaging/image/rauc-pre-install) accepts one
// older bundle while this file exists, and removes it.
constexpr const char* kAllowDowngradeFlag = "/run/dentmark/allow-downgrade";

// `rauc install` of the copied bundle, which is then removed. When RAUC refuses, what
// the box's handlers said is added from RAUC's journal ("# " lines): RAUC's own message
// names only the handler that failed, not why.
std::string install_command(const std::string& quoted_file) {
  return "t=$(date +%s); rauc install " + quoted_file + "; rc=$?; rm -f " + quoted_file +
         "; if [ $rc -ne 0 ]; then sleep 1; journalctl -u rauc.service --since=@$t -o cat --no-pager | "
         "sed -n 's/^# //p'; fi; exit $rc";
}

}  // namespace

UpdateResult update_box(const BoxAddress& address, const std::string& bundle, const UpdateOptions& o) {
  const auto say = [&](const std::string& line) {
    if (o.progress) o.progress(line);
  };
  if (!std::filesystem::is_regular_file(bundle)) throw UpdateError(bundle + ": no such bundle file");
  const auto t0 = std::chrono::steady_clock::now();
  const auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  const Box box(address);
  const std::string rauc_status = "rauc status --detailed --output-format=json";

  const RaucStatus before = parse_rauc_status(box.ssh_checked(rauc_status, "rauc status", 120.0));
  const std::optional<RaucSlot> old_slot = before.booted();
  if (!old_slot) throw UpdateError("rauc status on " + address.destination + ": no slot is booted");
  const std::string boot_id = box.ssh_checked("cat /proc/sys/kernel/random/boot_id", "boot id", 60.0);
  say(address.destination + " runs slot " + old_slot->name + " (" + old_slot->bootname + "), compatible '" +
      before.compatible + "'");

  say("copying " + bundle + " (" + std::to_string(std::filesystem::file_size(bundle) >> 20) + " MiB) to " +
      o.remote_file);
  box.copy(bundle, o.remote_file);
  if (o.allow_downgrade) {
    say("allowing one downgrade (" + std::string(kAllowDowngradeFlag) + ")");
    box.ssh_checked("mkdir -p /run/dentmark && touch " + std::string(kAllowDowngradeFlag), "allow downgrade",
                    60.0);
  }
  say("rauc install (the box checks signature, compatible and version)");
  const std::string file = quoted(o.remote_file);
  const process::Result install = box.ssh(install_command(file), 1800.0);
  if (install.exit_code != 0 || install.timed_out)
    throw UpdateError("the box refused the bundle: " + Box::last_lines(install.output));
  const RaucStatus installed = parse_rauc_status(box.ssh_checked(rauc_status, "rauc status", 120.0));
  UpdateResult result;
  result.old_slot = old_slot->name;
  result.new_slot = installed.boot_primary;
  if (result.new_slot.empty() || result.new_slot == result.old_slot)
    throw UpdateError("after the install the box would boot slot '" + result.new_slot + "' again");
  say("installed into " + result.new_slot + "; rebooting");
  box.ssh("systemctl reboot", 30.0);  // the connection drops as the box goes down

  bool reported_bad = false;
  while (elapsed() < o.timeout) {
    std::this_thread::sleep_for(std::chrono::duration<double>(o.poll_period));
    const process::Result id = box.ssh("cat /proc/sys/kernel/random/boot_id", 30.0);
    if (id.exit_code != 0 || id.output == boot_id) continue;  // still going down, or not up yet
    const process::Result status = box.ssh(rauc_status, 60.0);
    std::string units_command = "systemctl is-active";
    for (const std::string& u : o.units) units_command += " " + u;
    const process::Result units = box.ssh(units_command, 60.0);
    if (status.exit_code != 0 || units.timed_out) continue;
    RaucStatus after;
    try {
      after = parse_rauc_status(status.output);
    } catch (const UpdateError&) {
      continue;  // RAUC's service not up yet
    }
    result.verdict = judge(after, result.old_slot, result.new_slot, words(units.output));
    result.detail = "slot " +
                    (after.booted() ? after.booted()->name + " " + after.booted()->boot_status : "?") +
                    ", units: " + joined(words(units.output));
    if (result.verdict == Verdict::kNewSlotBad && !reported_bad) {
      say(result.new_slot + " booted but its health check failed; waiting for the fallback to " +
          result.old_slot);
      reported_bad = true;
    }
    if (result.verdict == Verdict::kUpdated || result.verdict == Verdict::kRolledBack) break;
  }
  result.seconds = elapsed();
  return result;
}

}  // namespace dentmark::update
