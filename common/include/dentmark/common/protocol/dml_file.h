#pragma once
// .dml files: exactly the bytes of one protocol frame (docs/protocol.md). Written
// atomically (temporary file in the same folder, fsync, rename), so a reader never
// sees a half-written file.

#include <cstdint>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "dentmark/common/protocol/codec.h"

namespace dentmark::protocol {

// I/O or decode problem with a .dml file. what() is one line:
//   "<path>: <problem>"  or  "<path>: byte <offset>: <kind>: <detail>"
class DmlFileError : public std::runtime_error {
 public:
  DmlFileError(const std::string& path, const std::string& problem);
  DmlFileError(const std::string& path, const DecodeError& error);
  bool is_decode_error() const { return decode_error_.has_value(); }
  const std::optional<DecodeError>& decode_error() const { return decode_error_; }

 private:
  std::optional<DecodeError> decode_error_;
};

// Encodes 'list' and writes it atomically. Throws EncodeError or DmlFileError.
void write_dml(const std::string& path, const DefectList& list, const EncodeOptions& options = {});
// Writes any frame bytes atomically. Throws DmlFileError.
void write_frame_file(const std::string& path, std::span<const std::uint8_t> frame);

// Reads a file's bytes, refusing (before reading) files larger than wire::kMaxFrameSize.
std::vector<std::uint8_t> read_frame_file(const std::string& path);
// Reads and decodes any protocol file. Throws DmlFileError.
Decoded read_protocol_file(const std::string& path, const DecodeOptions& options = {});
// Reads a .dml file that must hold a DefectList. Throws DmlFileError.
DefectList read_dml(const std::string& path, const DecodeOptions& options = {});

}  // namespace dentmark::protocol
