#pragma once
// The messages behind the golden vectors in tests/data/protocol/ (expected values of
// tests/data/protocol/golden.json, which the independent Python decoder checks).

#include <string>
#include <vector>

#include "dentmark/common/protocol/codec.h"

namespace dentmark::protocol::golden {

struct Vector {
  std::string file;  // in tests/data/protocol/
  Message message;
  std::uint64_t sequence;
  double send_time;
  bool sign;  // with golden.key
};

inline DefectList door_list() {
  DefectList l;
  l.job_id = 42;
  l.panel_id = "door-FL-0001";
  l.scan_time = 1750000000.25;
  l.frame = "sls";
  Defect dent;
  dent.id = 1;
  dent.defect_class = DefectClass::kDent;
  dent.position = {0.125, -0.0625, 0.75};
  dent.normal = {0.0, 0.0, 1.0};
  dent.diameter = 0.012;
  dent.height = -0.00015;
  dent.area = 0.000113;
  dent.score = 0.875;
  Defect bump;
  bump.id = 2;
  bump.defect_class = DefectClass::kBump;
  bump.position = {-0.25, 0.5, 0.8};
  bump.normal = {0.6, 0.0, 0.8};
  bump.diameter = 0.004;
  bump.height = 0.0003;
  bump.area = 0.0000126;
  bump.score = 0.5;
  l.defects = {dent, bump};
  return l;
}

inline std::vector<Vector> vectors() {
  Ack ack;
  ack.job_id = 42;
  ack.acked_sequence = 1;
  ack.count = 2;
  // SHA-256 of defect_list.dml's payload (bytes 32 .. 32+P-1), as §4.2 defines it.
  const char* digest_hex = "33ddbf94203459cbae1cf2de7f8a7e85af25ead8120b63022d167ec04da8562c";
  for (std::size_t i = 0; i < ack.digest.size(); ++i)
    ack.digest[i] = static_cast<std::uint8_t>(std::stoul(std::string(digest_hex + 2 * i, 2), nullptr, 16));
  MarkReport rep;
  rep.job_id = 42;
  rep.marks = {Mark{1, MarkOutcome::kMarked, MarkReason::kNone, 1750000030.5, {0.4, 0.1, 0.3}, 0.0015},
               Mark{2, MarkOutcome::kSkipped, MarkReason::kOutOfReach, 1750000031.0, {0.0, 0.0, 0.0}, 0.0}};
  Status st{EdgeState::kTracking, 0x5, 42, "0.1.0", 1, 1, 3600.5, 2, 1};
  MarkReport subscribe;  // host -> edge: "send me job 42's reports" (no records)
  subscribe.job_id = 42;
  ErrorMessage err{ErrorCode::kMalformedFrame, 0, 7, 12, "byte 12: over limit"};
  DefectList empty;
  empty.job_id = 43;
  empty.panel_id = "";
  empty.scan_time = 1750000100.0;
  empty.frame = "sls";
  return {
      {"defect_list.dml", door_list(), 1, 1750000001.5, false},
      {"defect_list_signed.dml", door_list(), 2, 1750000002.5, true},
      {"defect_list_empty.dml", empty, 3, 1750000100.5, false},
      {"ack.dml", ack, 100, 1750000001.75, false},
      {"mark_report.dml", rep, 101, 1750000032.0, false},
      {"status.dml", st, 102, 1750000033.0, false},
      {"error.dml", err, 103, 1750000034.0, false},
      {"subscribe.dml", subscribe, 4, 1750000002.0, false},
  };
}

// Frames of protocol 1.0 that a 1.1 decoder must still read (stored, never re-encoded).
struct OlderVector {
  std::string file;
  Message message;
};
inline std::vector<OlderVector> older_vectors() {
  return {{"status_1_0.dml", Status{EdgeState::kTracking, 0x5, 42, "0.1.0", 1, 0, 3600.5, 0, 0}}};
}

}  // namespace dentmark::protocol::golden
