#include "occgeo/replay/diagnostics.h"

#include <numeric>

namespace occgeo::replay {

void Diagnostics::warn(const std::string& kind, std::size_t line_number, const std::string& message) {
  const std::uint64_t seen = ++warnings_[kind];
  if (err_ == nullptr) return;
  if (seen <= static_cast<std::uint64_t>(print_limit_)) {
    *err_ << "occgeo replay: warning [" << kind << "]";
    if (line_number != 0) *err_ << " line " << line_number;
    *err_ << ": " << message << "\n";
  }
  if (seen == static_cast<std::uint64_t>(print_limit_)) {
    *err_ << "occgeo replay: further [" << kind << "] warnings are counted but not printed\n";
  }
}

std::uint64_t Diagnostics::warnings() const {
  return std::accumulate(warnings_.begin(), warnings_.end(), std::uint64_t{0},
                         [](std::uint64_t sum, const auto& entry) { return sum + entry.second; });
}

std::uint64_t Diagnostics::count(const std::string& kind) const {
  const auto it = warnings_.find(kind);
  return it == warnings_.end() ? 0 : it->second;
}

}  // namespace occgeo::replay
