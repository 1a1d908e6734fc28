#include "core/atomic_file.h"

#include "core/log.h"

#include <filesystem>
#include <fstream>
#include <system_error>

namespace theia {

void write_text_atomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throw_error("{}: cannot open for writing", tmp);
    f << text;
    f.flush();
    if (!f) throw_error("{}: write failed", tmp);
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw_error("{}: cannot rename to {}: {}", tmp, path, ec.message());
}

}  // namespace theia
