// Frame encoder and decoder (docs/protocol.md). Layout of a frame:
//   header (32) | payload (payload_length) | HMAC-SHA-256 (32, if flag 0) | CRC-32C (4)
// Payload: u16 head_size | head | u32 record_count | record_count × record_size.
#include "dentmark/common/protocol/codec.h"

#include <openssl/evp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_set>

#include "byte_io.h"
#include "dentmark/common/protocol/crc32c.h"
#include "dentmark/common/protocol/hmac_key.h"

namespace dentmark::protocol {
namespace {

using detail::ByteReader;
using detail::ByteWriter;

// ---- shared validation (encode refuses what decode would refuse) -------------------

// Largest deviation of |normal| from 1 accepted; the host normalises in double precision.
constexpr double kUnitTolerance = 1e-6;

bool printable(const std::string& s) {
  return std::all_of(s.begin(), s.end(), [](char c) { return c >= 0x20 && c <= 0x7E; });
}
bool finite3(const Eigen::Vector3d& v) {
  return v.allFinite();
}

void check_string(const std::string& s, const char* what) {
  if (s.size() > wire::kMaxStringLength)
    throw EncodeError(std::string(what) + ": " + std::to_string(s.size()) + " bytes > " +
                      std::to_string(wire::kMaxStringLength));
  if (!printable(s)) throw EncodeError(std::string(what) + ": not printable ASCII");
}
void check_count(std::size_t n, const char* what) {
  if (n > wire::kMaxRecords)
    throw EncodeError(std::string(what) + ": " + std::to_string(n) + " > limit " +
                      std::to_string(wire::kMaxRecords));
}
void check_finite(double v, const char* what) {
  if (!std::isfinite(v)) throw EncodeError(std::string(what) + ": not finite");
}

// ---- encoding -----------------------------------------------------------------------

class FrameBuilder {
 public:
  FrameBuilder(MessageType type, std::uint16_t record_size, const EncodeOptions& options)
      : w_(out_), options_(options) {
    double t =
        options.send_time
            ? *options.send_time
            : std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
    check_finite(t, "send_time");
    out_.reserve(256);
    w_.bytes(wire::kMagic);
    w_.u8(wire::kMajor);
    w_.u8(wire::kMinor);
    w_.u16(static_cast<std::uint16_t>(type));
    w_.u16(options.key ? wire::kFlagHmac : 0);
    w_.u16(record_size);
    w_.u32(0);  // payload length, patched in finish()
    w_.u64(options.sequence);
    w_.f64(t);
    w_.u16(0);  // head size, patched in end_head()
  }
  ByteWriter& w() { return w_; }
  void end_head(std::uint32_t record_count) {
    w_.patch_u16(wire::kHeaderSize, static_cast<std::uint16_t>(w_.size() - wire::kHeaderSize - 2));
    w_.u32(record_count);
  }
  std::vector<std::uint8_t> finish() {
    const std::size_t payload = w_.size() - wire::kHeaderSize;
    if (payload > wire::kMaxPayloadLength)
      throw EncodeError("payload of " + std::to_string(payload) + " bytes > limit");
    w_.patch_u32(wire::kOffPayloadLength, static_cast<std::uint32_t>(payload));
    if (options_.key) {
      const auto tag = options_.key->mac(out_);
      w_.bytes(tag);
    }
    w_.u32(crc32c(out_));
    return std::move(out_);
  }

 private:
  std::vector<std::uint8_t> out_;
  ByteWriter w_;
  const EncodeOptions& options_;
};

}  // namespace

std::vector<std::uint8_t> encode(const DefectList& list, const EncodeOptions& options) {
  check_string(list.panel_id, "panel_id");
  check_string(list.frame, "frame");
  if (list.frame.empty()) throw EncodeError("frame: empty");
  check_finite(list.scan_time, "scan_time");
  check_count(list.defects.size(), "defects");
  std::unordered_set<std::uint32_t> ids;
  for (const Defect& d : list.defects) {
    const std::string at = "defect " + std::to_string(d.id);
    if (!ids.insert(d.id).second) throw EncodeError(at + ": duplicate id");
    if (static_cast<std::uint8_t>(d.defect_class) > static_cast<std::uint8_t>(DefectClass::kNoise))
      throw EncodeError(at + ": bad class");
    if (!finite3(d.position) || !finite3(d.normal) || !std::isfinite(d.diameter) ||
        !std::isfinite(d.height) || !std::isfinite(d.area) || !std::isfinite(d.score))
      throw EncodeError(at + ": non-finite value");
    if (std::abs(d.normal.norm() - 1.0) > kUnitTolerance)
      throw EncodeError(at + ": normal is not unit length");
    if (d.diameter < 0 || d.area < 0) throw EncodeError(at + ": negative diameter or area");
    if (d.score < 0 || d.score > 1) throw EncodeError(at + ": score outside [0, 1]");
  }
  FrameBuilder f(MessageType::kDefectList, wire::kDefectRecordSize, options);
  auto& w = f.w();
  w.u64(list.job_id);
  w.f64(list.scan_time);
  w.str8(list.panel_id);
  w.str8(list.frame);
  f.end_head(static_cast<std::uint32_t>(list.defects.size()));
  for (const Defect& d : list.defects) {
    w.u32(d.id);
    w.u8(static_cast<std::uint8_t>(d.defect_class));
    w.u8(0);
    w.u16(0);
    for (int i = 0; i < 3; ++i) w.f64(d.position[i]);
    for (int i = 0; i < 3; ++i) w.f64(d.normal[i]);
    w.f64(d.diameter);
    w.f64(d.height);
    w.f64(d.area);
    w.f64(d.score);
  }
  return f.finish();
}

std::vector<std::uint8_t> encode(const Ack& ack, const EncodeOptions& options) {
  check_count(ack.count, "count");
  FrameBuilder f(MessageType::kAck, 0, options);
  auto& w = f.w();
  w.u64(ack.job_id);
  w.u64(ack.acked_sequence);
  w.u32(ack.count);
  w.bytes(ack.digest);
  f.end_head(0);
  return f.finish();
}

std::vector<std::uint8_t> encode(const MarkReport& report, const EncodeOptions& options) {
  check_count(report.marks.size(), "marks");
  for (const Mark& m : report.marks) {
    const std::string at = "mark of defect " + std::to_string(m.defect_id);
    if (static_cast<std::uint8_t>(m.outcome) > static_cast<std::uint8_t>(MarkOutcome::kFailed))
      throw EncodeError(at + ": bad outcome");
    if (static_cast<std::uint8_t>(m.reason) > static_cast<std::uint8_t>(MarkReason::kAborted))
      throw EncodeError(at + ": bad reason");
    if ((m.outcome == MarkOutcome::kMarked) != (m.reason == MarkReason::kNone))
      throw EncodeError(at + ": reason must be 'none' exactly when marked");
    if (!std::isfinite(m.time) || !finite3(m.tool_position) || !std::isfinite(m.estimated_error))
      throw EncodeError(at + ": non-finite value");
    if (m.estimated_error < 0) throw EncodeError(at + ": negative estimated error");
  }
  FrameBuilder f(MessageType::kMarkReport, wire::kMarkRecordSize, options);
  auto& w = f.w();
  w.u64(report.job_id);
  f.end_head(static_cast<std::uint32_t>(report.marks.size()));
  for (const Mark& m : report.marks) {
    w.u32(m.defect_id);
    w.u8(static_cast<std::uint8_t>(m.outcome));
    w.u8(static_cast<std::uint8_t>(m.reason));
    w.u16(0);
    w.f64(m.time);
    for (int i = 0; i < 3; ++i) w.f64(m.tool_position[i]);
    w.f64(m.estimated_error);
  }
  return f.finish();
}

std::vector<std::uint8_t> encode(const Status& status, const EncodeOptions& options) {
  if (static_cast<std::uint8_t>(status.state) > static_cast<std::uint8_t>(EdgeState::kSafe))
    throw EncodeError("state: bad value");
  check_finite(status.uptime, "uptime");
  if (status.uptime < 0) throw EncodeError("uptime: negative");
  check_string(status.firmware_version, "firmware_version");
  FrameBuilder f(MessageType::kStatus, 0, options);
  auto& w = f.w();
  w.u8(static_cast<std::uint8_t>(status.state));
  w.u8(status.protocol_major);
  w.u8(status.protocol_minor);
  w.u8(0);
  w.u32(status.fault_bits);
  w.u64(status.job_id);
  w.f64(status.uptime);
  w.str8(status.firmware_version);
  w.u32(status.defects_total);  // minor 1
  w.u32(status.defects_reported);
  f.end_head(0);
  return f.finish();
}

std::vector<std::uint8_t> encode(const ErrorMessage& error, const EncodeOptions& options) {
  const auto code = static_cast<std::uint16_t>(error.code);
  if (code < 1 || code > static_cast<std::uint16_t>(ErrorCode::kInternal))
    throw EncodeError("code: bad value");
  check_string(error.text, "text");
  FrameBuilder f(MessageType::kError, 0, options);
  auto& w = f.w();
  w.u16(code);
  w.u16(0);
  w.u32(error.byte_offset);
  w.u64(error.job_id);
  w.u64(error.offending_sequence);
  w.str8(error.text);
  f.end_head(0);
  return f.finish();
}

std::vector<std::uint8_t> encode(const Message& message, const EncodeOptions& options) {
  return std::visit([&](const auto& m) { return encode(m, options); }, message);
}

// ---- decoding -----------------------------------------------------------------------

std::size_t FrameHeader::frame_size() const {
  return wire::kHeaderSize + payload_length + (is_signed() ? wire::kHmacSize : 0) + wire::kCrcSize;
}

namespace {

DecodeError fail(DecodeErrorKind kind, std::size_t offset, std::string detail) {
  return DecodeError{kind, offset, std::move(detail)};
}

std::uint16_t min_record_size(MessageType t) {
  switch (t) {
    case MessageType::kDefectList:
      return wire::kDefectRecordSize;
    case MessageType::kMarkReport:
      return wire::kMarkRecordSize;
    default:
      return 0;
  }
}

// Reads the payload of one message type; 'r' spans the payload. Fields of newer
// minors beyond what this version knows are skipped by head_size and record_size.
class PayloadDecoder {
 public:
  PayloadDecoder(std::span<const std::uint8_t> frame, const FrameHeader& h, const DecodeOptions& o)
      : frame_(frame), h_(h), o_(o), r_(frame, wire::kHeaderSize, wire::kHeaderSize + h.payload_length) {}

  Result<Message> run() {
    if (!r_.has(2)) return trunc("head_size");
    const std::size_t head_size = r_.u16();
    head_end_ = r_.pos() + head_size;
    if (head_end_ > r_.end())
      return fail(DecodeErrorKind::kBadLength, r_.pos() - 2, "head_size beyond payload");
    head_ = ByteReader(frame_, r_.pos(), head_end_);
    switch (h_.type) {
      case MessageType::kDefectList:
        return defect_list();
      case MessageType::kAck:
        return ack();
      case MessageType::kMarkReport:
        return mark_report();
      case MessageType::kStatus:
        return status();
      case MessageType::kError:
        return error();
    }
    return fail(DecodeErrorKind::kBadEnum, wire::kOffType, "message type");
  }

 private:
  DecodeError trunc(const char* field) const {
    return fail(DecodeErrorKind::kBadLength, head_.pos(), std::string(field) + " does not fit in the head");
  }
  // Checks that the head holds 'n' more bytes for the named field.
  bool need(std::size_t n) const { return head_.has(n); }

  std::optional<DecodeError> str8(std::string& out, const char* field, bool allow_empty = true) {
    if (!need(1)) return trunc(field);
    const std::size_t at = head_.pos();
    const std::size_t n = head_.u8();
    if (!need(n))
      return fail(DecodeErrorKind::kBadLength, at, std::string(field) + " length beyond the head");
    auto s = head_.take(n);
    out.assign(s.begin(), s.end());
    if (!printable(out))
      return fail(DecodeErrorKind::kBadValue, at + 1, std::string(field) + ": not printable ASCII");
    if (!allow_empty && out.empty())
      return fail(DecodeErrorKind::kBadValue, at, std::string(field) + ": empty");
    return std::nullopt;
  }

  // Ends the head: exact size at our minor or older, at least our fields for newer ones.
  std::optional<DecodeError> end_head() {
    if (h_.minor <= wire::kMinor && head_.pos() != head_end_)
      return fail(DecodeErrorKind::kBadLength, head_.pos(),
                  "head_size larger than the fields of this version");
    r_.skip_to(head_end_);
    return std::nullopt;
  }

  // Reads the record count and checks that count × record_size fills the payload
  // exactly, before anything is allocated.
  Result<std::uint32_t> records() {
    if (!r_.has(4))
      return fail(DecodeErrorKind::kBadLength, r_.pos(), "record_count does not fit in the payload");
    const std::size_t at = r_.pos();
    const std::uint32_t n = r_.u32();
    const std::uint16_t min_size = min_record_size(h_.type);
    if (min_size == 0 && n != 0)
      return fail(DecodeErrorKind::kBadLength, at, "records in a message without records");
    if (n > o_.max_records || n > wire::kMaxRecords)
      return fail(DecodeErrorKind::kOverLimit, at,
                  "record_count " + std::to_string(n) + " > limit " +
                      std::to_string(std::min(o_.max_records, wire::kMaxRecords)));
    if (std::uint64_t{n} * h_.record_size != r_.remaining())
      return fail(DecodeErrorKind::kBadLength, at,
                  "record_count " + std::to_string(n) + " × record_size " + std::to_string(h_.record_size) +
                      " != " + std::to_string(r_.remaining()) + " bytes left in the payload");
    return n;
  }

  Result<Message> defect_list() {
    DefectList list;
    if (!need(16)) return trunc("job_id, scan_time");
    list.job_id = head_.u64();
    const std::size_t t_at = head_.pos();
    list.scan_time = head_.f64();
    if (!std::isfinite(list.scan_time)) return fail(DecodeErrorKind::kBadValue, t_at, "scan_time not finite");
    if (auto e = str8(list.panel_id, "panel_id")) return *e;
    if (auto e = str8(list.frame, "frame", false)) return *e;
    if (auto e = end_head()) return *e;
    auto n = records();
    if (!n) return n.error();
    list.defects.resize(n.value());
    std::unordered_set<std::uint32_t> ids;
    for (Defect& d : list.defects) {
      const std::size_t start = r_.pos();
      ByteReader rec(frame_, start, start + h_.record_size);
      d.id = rec.u32();
      if (!ids.insert(d.id).second) return fail(DecodeErrorKind::kBadValue, start, "duplicate defect id");
      const std::uint8_t cls = rec.u8();
      if (cls > static_cast<std::uint8_t>(DefectClass::kNoise))
        return fail(DecodeErrorKind::kBadEnum, start + 4, "defect class " + std::to_string(cls));
      d.defect_class = static_cast<DefectClass>(cls);
      if (rec.u8() != 0 || rec.u16() != 0)
        return fail(DecodeErrorKind::kBadValue, start + 5, "reserved bytes not 0");
      for (int i = 0; i < 3; ++i) d.position[i] = rec.f64();
      for (int i = 0; i < 3; ++i) d.normal[i] = rec.f64();
      d.diameter = rec.f64();
      d.height = rec.f64();
      d.area = rec.f64();
      d.score = rec.f64();
      if (!d.position.allFinite()) return fail(DecodeErrorKind::kBadValue, start + 8, "position not finite");
      if (!d.normal.allFinite() || std::abs(d.normal.norm() - 1.0) > kUnitTolerance)
        return fail(DecodeErrorKind::kBadValue, start + 32, "normal not a finite unit vector");
      if (!std::isfinite(d.diameter) || d.diameter < 0)
        return fail(DecodeErrorKind::kBadValue, start + 56, "diameter not finite and ≥ 0");
      if (!std::isfinite(d.height)) return fail(DecodeErrorKind::kBadValue, start + 64, "height not finite");
      if (!std::isfinite(d.area) || d.area < 0)
        return fail(DecodeErrorKind::kBadValue, start + 72, "area not finite and ≥ 0");
      if (!(d.score >= 0 && d.score <= 1))
        return fail(DecodeErrorKind::kBadValue, start + 80, "score outside [0, 1]");
      r_.skip_to(start + h_.record_size);
    }
    return Message(std::move(list));
  }

  Result<Message> ack() {
    Ack a;
    if (!need(52)) return trunc("ack fields");
    a.job_id = head_.u64();
    a.acked_sequence = head_.u64();
    const std::size_t at = head_.pos();
    a.count = head_.u32();
    if (a.count > wire::kMaxRecords) return fail(DecodeErrorKind::kOverLimit, at, "count > limit");
    auto d = head_.take(32);
    std::copy(d.begin(), d.end(), a.digest.begin());
    if (auto e = end_head()) return *e;
    auto n = records();
    if (!n) return n.error();
    return Message(a);
  }

  Result<Message> mark_report() {
    MarkReport rep;
    if (!need(8)) return trunc("job_id");
    rep.job_id = head_.u64();
    if (auto e = end_head()) return *e;
    auto n = records();
    if (!n) return n.error();
    rep.marks.resize(n.value());
    for (Mark& m : rep.marks) {
      const std::size_t start = r_.pos();
      ByteReader rec(frame_, start, start + h_.record_size);
      m.defect_id = rec.u32();
      const std::uint8_t outcome = rec.u8();
      const std::uint8_t reason = rec.u8();
      if (outcome > static_cast<std::uint8_t>(MarkOutcome::kFailed))
        return fail(DecodeErrorKind::kBadEnum, start + 4, "mark outcome " + std::to_string(outcome));
      if (reason > static_cast<std::uint8_t>(MarkReason::kAborted))
        return fail(DecodeErrorKind::kBadEnum, start + 5, "mark reason " + std::to_string(reason));
      m.outcome = static_cast<MarkOutcome>(outcome);
      m.reason = static_cast<MarkReason>(reason);
      if ((m.outcome == MarkOutcome::kMarked) != (m.reason == MarkReason::kNone))
        return fail(DecodeErrorKind::kBadValue, start + 5, "reason must be 'none' exactly when marked");
      if (rec.u16() != 0) return fail(DecodeErrorKind::kBadValue, start + 6, "reserved bytes not 0");
      m.time = rec.f64();
      for (int i = 0; i < 3; ++i) m.tool_position[i] = rec.f64();
      m.estimated_error = rec.f64();
      if (!std::isfinite(m.time)) return fail(DecodeErrorKind::kBadValue, start + 8, "time not finite");
      if (!m.tool_position.allFinite())
        return fail(DecodeErrorKind::kBadValue, start + 16, "tool position not finite");
      if (!std::isfinite(m.estimated_error) || m.estimated_error < 0)
        return fail(DecodeErrorKind::kBadValue, start + 40, "estimated error not finite and ≥ 0");
      r_.skip_to(start + h_.record_size);
    }
    return Message(std::move(rep));
  }

  Result<Message> status() {
    Status s;
    if (!need(24)) return trunc("status fields");
    const std::size_t at = head_.pos();
    const std::uint8_t state = head_.u8();
    if (state > static_cast<std::uint8_t>(EdgeState::kSafe))
      return fail(DecodeErrorKind::kBadEnum, at, "state " + std::to_string(state));
    s.state = static_cast<EdgeState>(state);
    s.protocol_major = head_.u8();
    s.protocol_minor = head_.u8();
    if (head_.u8() != 0) return fail(DecodeErrorKind::kBadValue, at + 3, "reserved byte not 0");
    s.fault_bits = head_.u32();
    s.job_id = head_.u64();
    s.uptime = head_.f64();
    if (!std::isfinite(s.uptime) || s.uptime < 0)
      return fail(DecodeErrorKind::kBadValue, at + 16, "uptime not finite and ≥ 0");
    if (auto e = str8(s.firmware_version, "firmware_version")) return *e;
    if (h_.minor >= 1) {
      if (!need(8)) return trunc("job progress (minor 1)");
      s.defects_total = head_.u32();
      s.defects_reported = head_.u32();
    }
    if (auto e = end_head()) return *e;
    auto n = records();
    if (!n) return n.error();
    return Message(std::move(s));
  }

  Result<Message> error() {
    ErrorMessage m;
    if (!need(24)) return trunc("error fields");
    const std::size_t at = head_.pos();
    const std::uint16_t code = head_.u16();
    if (code < 1 || code > static_cast<std::uint16_t>(ErrorCode::kInternal))
      return fail(DecodeErrorKind::kBadEnum, at, "error code " + std::to_string(code));
    m.code = static_cast<ErrorCode>(code);
    if (head_.u16() != 0) return fail(DecodeErrorKind::kBadValue, at + 2, "reserved bytes not 0");
    m.byte_offset = head_.u32();
    m.job_id = head_.u64();
    m.offending_sequence = head_.u64();
    if (auto e = str8(m.text, "text")) return *e;
    if (auto e = end_head()) return *e;
    auto n = records();
    if (!n) return n.error();
    return Message(std::move(m));
  }

  std::span<const std::uint8_t> frame_;
  const FrameHeader& h_;
  const DecodeOptions& o_;
  ByteReader r_;
  ByteReader head_{frame_, 0, 0};
  std::size_t head_end_ = 0;
};

}  // namespace

Result<FrameHeader> decode_header(std::span<const std::uint8_t> bytes, const DecodeOptions& options) {
  // Checks run in byte order, so a stream reader can refuse a bad frame as soon as
  // the offending byte has arrived.
  for (std::size_t i = 0; i < wire::kMagic.size(); ++i) {
    if (i >= bytes.size())
      return fail(DecodeErrorKind::kTruncated, bytes.size(), "frame ends inside the magic");
    if (bytes[i] != wire::kMagic[i])
      return fail(DecodeErrorKind::kBadMagic, i, "not a dentmark frame (magic 'DMKL')");
  }
  if (bytes.size() < wire::kHeaderSize)
    return fail(DecodeErrorKind::kTruncated, bytes.size(),
                "frame of " + std::to_string(bytes.size()) + " bytes ends inside the 32-byte header");
  ByteReader r(bytes, wire::kOffMajor, wire::kHeaderSize);
  FrameHeader h;
  h.major = r.u8();
  h.minor = r.u8();
  if (h.major != wire::kMajor)
    return fail(DecodeErrorKind::kUnsupportedVersion, wire::kOffMajor,
                "major version " + std::to_string(h.major) + " (this build reads " +
                    std::to_string(wire::kMajor) + ")");
  const std::uint16_t type = r.u16();
  if (type < 1 || type > static_cast<std::uint16_t>(MessageType::kError))
    return fail(DecodeErrorKind::kBadEnum, wire::kOffType, "message type " + std::to_string(type));
  h.type = static_cast<MessageType>(type);
  h.flags = r.u16();
  if ((h.flags & ~wire::kKnownFlags) != 0)
    return fail(DecodeErrorKind::kBadEnum, wire::kOffFlags, "unknown flag bits " + std::to_string(h.flags));
  h.record_size = r.u16();
  const std::uint16_t min_size = min_record_size(h.type);
  const bool record_size_ok =
      min_size == 0 ? h.record_size == 0
                    : (h.minor <= wire::kMinor ? h.record_size == min_size : h.record_size >= min_size);
  if (!record_size_ok)
    return fail(DecodeErrorKind::kBadLength, wire::kOffRecordSize,
                "record_size " + std::to_string(h.record_size) + " for " + to_string(h.type) +
                    " (minor 0: " + std::to_string(min_size) + ")");
  h.payload_length = r.u32();
  const std::size_t limit = std::min(options.max_frame_size, wire::kMaxFrameSize);
  // frame_size() cannot overflow: payload_length < 2^32 and size_t is 64-bit on our targets.
  if (h.frame_size() > limit)
    return fail(DecodeErrorKind::kOverLimit, wire::kOffPayloadLength,
                "frame of " + std::to_string(h.frame_size()) + " bytes > limit " + std::to_string(limit));
  h.sequence = r.u64();
  h.send_time = r.f64();
  if (!std::isfinite(h.send_time))
    return fail(DecodeErrorKind::kBadValue, wire::kOffSendTime, "send_time not finite");
  return h;
}

DecodeResult decode(std::span<const std::uint8_t> bytes, const DecodeOptions& options) {
  auto hr = decode_header(bytes, options);
  if (!hr) return hr.error();
  const FrameHeader& h = hr.value();
  const std::size_t total = h.frame_size();
  if (bytes.size() < total)
    return fail(
        DecodeErrorKind::kTruncated, bytes.size(),
        "frame of " + std::to_string(bytes.size()) + " bytes; header announces " + std::to_string(total));
  if (bytes.size() > total)
    return fail(DecodeErrorKind::kBadLength, total,
                std::to_string(bytes.size() - total) + " bytes after the end of the frame");
  const std::size_t crc_at = total - wire::kCrcSize;
  ByteReader cr(bytes, crc_at, total);
  const std::uint32_t crc = cr.u32();
  const std::uint32_t expected = crc32c(bytes.first(crc_at));
  if (crc != expected) return fail(DecodeErrorKind::kBadCrc, crc_at, "CRC-32C mismatch");

  bool authenticated = false;
  const std::size_t signed_end = wire::kHeaderSize + h.payload_length;
  if (options.key) {
    if (!h.is_signed())
      return fail(DecodeErrorKind::kUnsigned, wire::kOffFlags, "unsigned frame but a key is configured");
    if (!options.key->verify(bytes.first(signed_end), bytes.subspan(signed_end, wire::kHmacSize)))
      return fail(DecodeErrorKind::kBadHmac, signed_end,
                  "HMAC-SHA-256 mismatch (wrong key or altered frame)");
    authenticated = true;
  }
  PayloadDecoder pd(bytes, h, options);
  auto m = pd.run();
  if (!m) return m.error();
  return Decoded{h, std::move(m.value()), authenticated};
}

Digest payload_digest(std::span<const std::uint8_t> frame) {
  Digest d{};
  std::size_t len = 0;
  if (frame.size() >= wire::kHeaderSize) {
    ByteReader r(frame, wire::kOffPayloadLength, wire::kOffPayloadLength + 4);
    len = std::min<std::size_t>(r.u32(), frame.size() - wire::kHeaderSize);
  }
  unsigned int out_len = 0;
  if (EVP_Digest(frame.data() + std::min(frame.size(), wire::kHeaderSize), len, d.data(), &out_len,
                 EVP_sha256(), nullptr) != 1)
    throw std::runtime_error("SHA-256 failed (OpenSSL)");
  return d;
}

const char* to_string(DecodeErrorKind kind) {
  switch (kind) {
    case DecodeErrorKind::kTruncated:
      return "truncated";
    case DecodeErrorKind::kBadMagic:
      return "bad magic";
    case DecodeErrorKind::kUnsupportedVersion:
      return "unsupported version";
    case DecodeErrorKind::kBadEnum:
      return "bad enum value";
    case DecodeErrorKind::kOverLimit:
      return "over limit";
    case DecodeErrorKind::kBadLength:
      return "bad length";
    case DecodeErrorKind::kBadCrc:
      return "bad CRC";
    case DecodeErrorKind::kUnsigned:
      return "unsigned";
    case DecodeErrorKind::kBadHmac:
      return "bad HMAC";
    case DecodeErrorKind::kBadValue:
      return "bad value";
  }
  return "?";
}

std::string DecodeError::message() const {
  return "byte " + std::to_string(offset) + ": " + to_string(kind) + ": " + detail;
}

const char* to_string(MessageType type) {
  switch (type) {
    case MessageType::kDefectList:
      return "DefectList";
    case MessageType::kAck:
      return "Ack";
    case MessageType::kMarkReport:
      return "MarkReport";
    case MessageType::kStatus:
      return "Status";
    case MessageType::kError:
      return "Error";
  }
  return "?";
}

const char* to_string(DefectClass c) {
  constexpr const char* kNames[] = {"dent", "bump", "hole", "design_feature", "noise"};
  const auto i = static_cast<std::size_t>(c);
  return i < std::size(kNames) ? kNames[i] : "?";
}
const char* to_string(MarkOutcome o) {
  constexpr const char* kNames[] = {"marked", "skipped", "failed"};
  const auto i = static_cast<std::size_t>(o);
  return i < std::size(kNames) ? kNames[i] : "?";
}
const char* to_string(MarkReason r) {
  constexpr const char* kNames[] = {"none",        "not_markable",   "out_of_reach", "tracking_lost",
                                    "robot_fault", "emergency_stop", "timeout",      "aborted"};
  const auto i = static_cast<std::size_t>(r);
  return i < std::size(kNames) ? kNames[i] : "?";
}
const char* to_string(EdgeState s) {
  constexpr const char* kNames[] = {"idle", "job_received", "tracking", "marking", "done", "safe"};
  const auto i = static_cast<std::size_t>(s);
  return i < std::size(kNames) ? kNames[i] : "?";
}
const char* to_string(ErrorCode c) {
  constexpr const char* kNames[] = {"?",    "malformed_frame", "unauthenticated", "unsupported",
                                    "busy", "internal"};
  const auto i = static_cast<std::size_t>(c);
  return i < std::size(kNames) ? kNames[i] : "?";
}

}  // namespace dentmark::protocol
