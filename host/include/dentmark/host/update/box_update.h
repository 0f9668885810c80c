#pragma once
// `dentmark update --to BOX BUNDLE` (docs/deploy.md, "Updates"): a RAUC bundle onto an
// edge box over ssh. The box's own RAUC checks the bundle (signature, compatible,
// version); this side copies it, runs `rauc install`, reboots the box into the other
// slot and waits until the box says which slot it runs and whether the health check
// marked it good, or that the bootloader fell back to the old slot.

#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace dentmark::update {

class UpdateError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// One slot of `rauc status --detailed --output-format=json`.
struct RaucSlot {
  std::string name;         // "rootfs.0"
  std::string bootname;     // "A"
  std::string state;        // "booted", "active", "inactive"
  std::string boot_status;  // "good", "bad", "" (unknown)
};

struct RaucStatus {
  std::string compatible;
  std::string boot_primary;  // the slot the bootloader tries first
  std::vector<RaucSlot> slots;
  // The slot in state "booted" (RAUC's "booted" field may be a bootname or a device).
  std::optional<RaucSlot> booted() const;
};

// Parses RAUC's JSON; throws UpdateError naming the field that is missing or wrong.
RaucStatus parse_rauc_status(const std::string& json);

// Where the box is after the reboot, judged from its RAUC status and the states of its
// health-check and mark-good units (`systemctl is-active`).
enum class Verdict {
  kWaiting,     // the box has not settled yet (units still running, or no answer)
  kUpdated,     // the new slot booted, its health check passed, RAUC marked it good
  kNewSlotBad,  // the new slot booted and its health check failed: a fallback follows
  kRolledBack,  // the box runs the old slot again
};
Verdict judge(const RaucStatus& after, const std::string& old_slot, const std::string& new_slot,
              const std::vector<std::string>& unit_states);

struct BoxAddress {
  std::string destination;  // [user@]host
  int ssh_port = 22;
  std::string identity;                  // ssh private key file; empty: ssh's default
  std::vector<std::string> ssh_options;  // more `-o` options for ssh and scp
};

struct UpdateOptions {
  std::string remote_file = "/data/update.raucb";  // on the box's data partition
  double timeout = 1800.0;                         // s for the whole update (install, reboot, settle)
  double poll_period = 5.0;                        // s between looks at the rebooting box
  bool allow_downgrade = false;  // let the box's pre-install handler accept an older version, once
  std::vector<std::string> units = {"dentmark-health.service", "dentmark-mark-good.service"};
  std::function<void(const std::string&)> progress;  // one line per step
};

struct UpdateResult {
  Verdict verdict = Verdict::kWaiting;
  std::string old_slot, new_slot;  // slot names
  std::string detail;              // what the box said last
  double seconds = 0.0;
};

// Runs the whole update. Throws UpdateError when a step cannot run (no ssh answer, the
// copy failed, RAUC refused the bundle: its message included). The result says where
// the box ended; kWaiting there means the timeout ran out.
UpdateResult update_box(const BoxAddress& box, const std::string& bundle, const UpdateOptions& options);

}  // namespace dentmark::update
