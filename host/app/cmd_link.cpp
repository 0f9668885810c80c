// `dentmark send` and `dentmark inspect`: the host end of the link and a viewer for
// protocol files (.dml holds exactly one frame's bytes; docs/protocol.md).
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "commands.h"
#include "dentmark/common/atomic_file.h"
#include "dentmark/common/log.h"
#include "dentmark/common/protocol/dml_file.h"
#include "dentmark/common/protocol/hmac_key.h"
#include "dentmark/common/protocol/job_session.h"
#include "dentmark/common/protocol/link_client.h"
#include "dentmark/common/protocol/marks_json.h"
#include "dentmark/common/protocol/socket_io.h"

namespace dentmark::cli {
namespace {

namespace pr = protocol;
using nlohmann::ordered_json;

std::string hex(std::span<const std::uint8_t> b) {
  static const char* d = "0123456789abcdef";
  std::string s;
  for (auto x : b) {
    s += d[x >> 4];
    s += d[x & 15];
  }
  return s;
}

ordered_json vec(const Eigen::Vector3d& v) {
  return ordered_json::array({v.x(), v.y(), v.z()});
}

ordered_json to_json(const pr::Message& m) {
  return std::visit(
      [](const auto& x) -> ordered_json {
        using T = std::decay_t<decltype(x)>;
        ordered_json j;
        if constexpr (std::is_same_v<T, pr::DefectList>) {
          j["job_id"] = x.job_id;
          j["panel_id"] = x.panel_id;
          j["scan_time"] = x.scan_time;
          j["frame"] = x.frame;
          j["defects"] = ordered_json::array();
          for (const auto& d : x.defects)
            j["defects"].push_back({{"id", d.id},
                                    {"class", pr::to_string(d.defect_class)},
                                    {"position", vec(d.position)},
                                    {"normal", vec(d.normal)},
                                    {"diameter", d.diameter},
                                    {"height", d.height},
                                    {"area", d.area},
                                    {"score", d.score}});
        } else if constexpr (std::is_same_v<T, pr::Ack>) {
          j = {{"job_id", x.job_id},
               {"acked_sequence", x.acked_sequence},
               {"count", x.count},
               {"digest", hex(x.digest)}};
        } else if constexpr (std::is_same_v<T, pr::MarkReport>) {
          j["job_id"] = x.job_id;
          j["marks"] = ordered_json::array();
          for (const auto& k : x.marks)
            j["marks"].push_back({{"defect_id", k.defect_id},
                                  {"outcome", pr::to_string(k.outcome)},
                                  {"reason", pr::to_string(k.reason)},
                                  {"time", k.time},
                                  {"tool_position", vec(k.tool_position)},
                                  {"estimated_error", k.estimated_error}});
        } else if constexpr (std::is_same_v<T, pr::Status>) {
          j = {
              {"state", pr::to_string(x.state)},
              {"fault_bits", x.fault_bits},
              {"job_id", x.job_id},
              {"firmware_version", x.firmware_version},
              {"protocol_version", std::to_string(x.protocol_major) + "." + std::to_string(x.protocol_minor)},
              {"uptime", x.uptime},
              {"defects_total", x.defects_total},
              {"defects_reported", x.defects_reported}};
        } else {
          j = {{"code", pr::to_string(x.code)},
               {"job_id", x.job_id},
               {"offending_sequence", x.offending_sequence},
               {"byte_offset", x.byte_offset},
               {"text", x.text}};
        }
        return j;
      },
      m);
}

ordered_json to_json(const pr::Decoded& d, std::size_t size) {
  const auto& h = d.header;
  ordered_json j;
  j["type"] = pr::to_string(h.type);
  j["version"] = std::to_string(h.major) + "." + std::to_string(h.minor);
  j["sequence"] = h.sequence;
  j["send_time"] = h.send_time;
  j["signed"] = h.is_signed();
  j["authenticated"] = d.authenticated;
  j["frame_bytes"] = size;
  j["message"] = to_json(d.message);
  return j;
}

std::string mm(double m) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3f", m * 1000.0);
  return b;
}

// Human-readable summary (lengths in mm for people).
void print_text(std::ostream& os, const pr::Decoded& d, std::size_t size) {
  const auto& h = d.header;
  os << pr::to_string(h.type) << " (protocol " << int(h.major) << "." << int(h.minor) << ", " << size
     << " bytes, sequence " << h.sequence << ", "
     << (h.is_signed() ? (d.authenticated ? "signed, verified" : "signed, not verified") : "unsigned")
     << ")\n";
  if (const auto* l = std::get_if<pr::DefectList>(&d.message)) {
    os << "job " << l->job_id << ", panel '" << l->panel_id << "', frame '" << l->frame << "', scan time "
       << std::to_string(l->scan_time) << " s, " << l->defects.size() << " defects\n";
    for (const auto& x : l->defects)
      os << "  #" << x.id << " " << pr::to_string(x.defect_class) << " at (" << mm(x.position.x()) << ", "
         << mm(x.position.y()) << ", " << mm(x.position.z()) << ") mm, diameter " << mm(x.diameter)
         << " mm, height " << mm(x.height) << " mm, score " << x.score << "\n";
    return;
  }
  os << to_json(d.message).dump(2) << "\n";
}

struct SendOptions {
  std::string file;
  std::string to;
  std::string key_file;
  double timeout = 5.0;
  int attempts = 3;
  bool wait = false;
  double job_timeout = 600.0;
  std::string json_out;
};

std::optional<pr::ClientOptions> client_options(const std::string& option, const std::string& to,
                                                const pr::HmacKey* key, double timeout, int attempts) {
  pr::ClientOptions co;
  if (!pr::parse_endpoint(to, &co.host, &co.port)) {
    log::error(option + "'" + to + "': expected HOST:PORT");
    return std::nullopt;
  }
  co.reply_timeout = std::chrono::milliseconds(static_cast<long>(timeout * 1000));
  co.connect_timeout = co.reply_timeout;
  co.attempts = attempts;
  co.key = key;
  return co;
}

// Exit codes: 0 acknowledged (with --wait: every dent, bump and hole marked), 1 link
// failure or refusal, 2 bad input, 3 (--wait) a defect was not marked or the job timed out.
int run_send(const SendOptions& o) {
  std::optional<pr::HmacKey> key;
  pr::DefectList list;
  try {
    if (!o.key_file.empty()) key = pr::HmacKey::load(o.key_file);
    list = pr::read_dml(o.file);
  } catch (const std::exception& e) {
    log::error(e.what());
    return 2;
  }
  const auto co = client_options("--to ", o.to, key ? &*key : nullptr, o.timeout, o.attempts);
  if (!co) return 2;
  pr::JobSession session(*co);
  pr::JobOutcome outcome;
  try {
    const pr::SentJob sent = session.send(list);
    std::cout << "ack job " << sent.ack.job_id << ": " << sent.ack.count << " defects, sequence "
              << sent.ack.acked_sequence << ", digest " << hex(sent.ack.digest)
              << (sent.ack_matches ? " (matches)" : " (MISMATCH)")
              << (sent.authenticated ? ", authenticated" : "") << "\n";
    if (!sent.ack_matches) return 1;
    if (!o.wait) return 0;
    pr::JobWaitOptions wo;
    wo.timeout = o.job_timeout;
    wo.on_mark = [&](const pr::Mark& m) {
      log::info(
          "defect " + std::to_string(m.defect_id) + ": " + pr::to_string(m.outcome) +
          (m.outcome == pr::MarkOutcome::kMarked ? "" : std::string(" (") + pr::to_string(m.reason) + ")"));
    };
    outcome = session.wait(list, wo);
  } catch (const pr::Refused& e) {
    log::error(o.to + " refused " + o.file + ": " + e.what());
    return 1;
  } catch (const pr::LinkError& e) {
    log::error(e.what());
    return 1;
  }
  std::cout << pr::marks_table(list, outcome);
  if (!o.json_out.empty()) {
    try {
      files::write_atomically(o.json_out, pr::marks_json(list, outcome));
    } catch (const files::FileError& e) {
      log::error(e.what());
      return 2;
    }
  }
  if (!outcome.complete) {
    log::error("job " + std::to_string(list.job_id) + ": " + std::to_string(outcome.marks.size()) + " of " +
               std::to_string(list.defects.size()) + " defects reported within " +
               std::to_string(o.job_timeout) + " s");
    return 3;
  }
  const bool ok = pr::all_marked(list, outcome);
  std::cout << (ok ? "every defect marked\n" : "NOT every defect was marked\n");
  return ok ? 0 : 3;
}

struct StatusOptions {
  std::string to;
  std::string key_file;
  double timeout = 5.0;
  bool json = false;
};

std::string fault_names(std::uint32_t bits) {
  static const char* names[] = {"e-stop", "robot", "camera", "tracking", "link", "calibration"};
  std::string s;
  for (int i = 0; i < 32; ++i) {
    if (!(bits & (1u << i))) continue;
    if (!s.empty()) s += ", ";
    s += i < 6 ? names[i] : "bit " + std::to_string(i);
  }
  return s.empty() ? "none" : s;
}

int run_status(const StatusOptions& o) {
  std::optional<pr::HmacKey> key;
  try {
    if (!o.key_file.empty()) key = pr::HmacKey::load(o.key_file);
  } catch (const std::exception& e) {
    log::error(e.what());
    return 2;
  }
  const auto co = client_options("", o.to, key ? &*key : nullptr, o.timeout, 1);
  if (!co) return 2;
  pr::Status s;
  try {
    s = pr::JobSession(*co).status();
  } catch (const std::exception& e) {
    log::error(o.to + ": " + e.what());
    return 1;
  }
  if (o.json) {
    ordered_json j = to_json(pr::Message(s));
    j["faults"] = fault_names(s.fault_bits);
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::printf("edge %s: %s, faults: %s\n", o.to.c_str(), pr::to_string(s.state),
              fault_names(s.fault_bits).c_str());
  if (s.job_id != 0)
    std::printf("job %llu: %u of %u defects reported\n", static_cast<unsigned long long>(s.job_id),
                s.defects_reported, s.defects_total);
  std::printf("up %.1f s, firmware %s, protocol %d.%d\n", s.uptime, s.firmware_version.c_str(),
              s.protocol_major, s.protocol_minor);
  return 0;
}

struct InspectOptions {
  std::string file;
  std::string key_file;
  bool json = false;
};

int run_inspect(const InspectOptions& o) {
  try {
    std::optional<pr::HmacKey> key;
    if (!o.key_file.empty()) key = pr::HmacKey::load(o.key_file);
    pr::DecodeOptions dopt;
    dopt.key = key ? &*key : nullptr;
    const auto bytes = pr::read_frame_file(o.file);
    auto r = pr::decode(bytes, dopt);
    if (!r) throw pr::DmlFileError(o.file, r.error());
    if (o.json) {
      auto j = to_json(r.value(), bytes.size());
      j["payload_sha256"] = hex(pr::payload_digest(bytes));
      std::cout << j.dump(2) << "\n";
    } else {
      print_text(std::cout, r.value(), bytes.size());
    }
  } catch (const std::exception& e) {
    log::error(e.what());
    return 2;
  }
  return 0;
}

}  // namespace

void register_link(CLI::App& app) {
  auto so = std::make_shared<SendOptions>();
  CLI::App* send = app.add_subcommand("send", "Send a defect list (.dml) to the edge box and print its Ack");
  send->add_option("file", so->file, "Defect list file (.dml)")->required();
  send->add_option("--to", so->to, "Edge box HOST:PORT")->required();
  send->add_option("--key", so->key_file,
                   "Pre-shared HMAC-SHA-256 key file (hex): sign and require signed replies");
  send->add_option("--timeout", so->timeout, "Connect and reply timeout per attempt, s")
      ->check(CLI::Range(0.01, 600.0));
  send->add_option("--attempts", so->attempts, "Connection attempts")->check(CLI::Range(1, 100));
  send->add_flag("--wait", so->wait,
                 "Wait for the job's mark reports and print them (exit 3 if not all marked)");
  send->add_option("--job-timeout", so->job_timeout, "With --wait: s to wait for every defect's outcome")
      ->check(CLI::Range(1.0, 86400.0));
  send->add_option("--json", so->json_out, "With --wait: write the outcomes as dentmark.marks/1 JSON");
  send->callback([so] { exit_code() = run_send(*so); });

  auto st = std::make_shared<StatusOptions>();
  CLI::App* status = app.add_subcommand("status", "Print the edge box's state, faults, job and version");
  status->add_option("edge", st->to, "Edge box HOST:PORT")->required();
  status->add_option("--key", st->key_file, "Pre-shared HMAC-SHA-256 key file (hex)");
  status->add_option("--timeout", st->timeout, "Connect and reply timeout, s")
      ->check(CLI::Range(0.01, 600.0));
  status->add_flag("--json", st->json, "JSON output");
  status->callback([st] { exit_code() = run_status(*st); });

  auto io = std::make_shared<InspectOptions>();
  CLI::App* inspect = app.add_subcommand("inspect", "Print a protocol file (.dml or any frame)");
  inspect->add_option("file", io->file, "Protocol file")->required();
  inspect->add_flag("--json", io->json, "JSON output");
  inspect->add_option("--key", io->key_file, "Key file to verify the signature");
  inspect->callback([io] { exit_code() = run_inspect(*io); });
}

}  // namespace dentmark::cli
