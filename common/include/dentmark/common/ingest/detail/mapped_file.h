#pragma once
// Read-only memory map of a whole file: big scans are parsed in place, no copies.

#include <cstddef>
#include <string>
#include <string_view>

namespace dentmark::ingest::detail {

class MappedFile {
 public:
  explicit MappedFile(const std::string& path);  // throws IngestError
  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  const char* data() const { return data_; }
  std::size_t size() const { return size_; }
  std::string_view view() const { return {data_, size_}; }

 private:
  const char* data_ = nullptr;
  std::size_t size_ = 0;
  bool mapped_ = false;
};

}  // namespace dentmark::ingest::detail
