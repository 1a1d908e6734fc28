// Text outputs (logs, manifests) written so that a crash never leaves a
// truncated file at the path: to PATH.tmp, flushed, then renamed.
#pragma once

#include <string>

namespace theia {

// Throws theia::Error naming the path when it cannot be written.
void write_text_atomically(const std::string& path, const std::string& text);

}  // namespace theia
