#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace occgeo::mapping {

// An immutable-once-published table of a model's tiles by key, in two levels: a directory of chunks, each holding the
// tiles of one block of neighbouring keys in key order, shared by every copy of the table it did not change in.
// Copying the table copies the directory (a pointer per chunk); apply() copies the chunks its changes lie in. A model
// that publishes a snapshot per scan keeps one of these in step with its tiles, so that a snapshot costs what the scan
// changed rather than a copy of every tile pointer.
//
// Traits gives, for a Key: code(key), a std::uint64_t that orders and identifies keys, and chunk(key), the
// std::uint64_t of the block of keys it belongs to (keys of one chunk are few: at most a few hundred).
template <typename Key, typename Value, typename Traits>
class ChunkedTable {
 public:
  using ValuePtr = std::shared_ptr<const Value>;

  // The value of key, or nullptr.
  [[nodiscard]] const Value* find(const Key& key) const {
    const std::uint64_t chunk_code = Traits::chunk(key);
    const auto chunk = std::lower_bound(chunks_.begin(), chunks_.end(), chunk_code,
                                        [](const ChunkEntry& entry, std::uint64_t c) { return entry.first < c; });
    if (chunk == chunks_.end() || chunk->first != chunk_code) return nullptr;
    const std::uint64_t code = Traits::code(key);
    const auto& entries = chunk->second->entries;
    const auto entry = std::lower_bound(entries.begin(), entries.end(), code,
                                        [](const Entry& e, std::uint64_t c) { return Traits::code(e.first) < c; });
    return entry != entries.end() && Traits::code(entry->first) == code ? entry->second.get() : nullptr;
  }
  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] bool empty() const { return size_ == 0; }
  // Chunks in the directory (what a copy of the table copies).
  [[nodiscard]] std::size_t chunk_count() const { return chunks_.size(); }

  // visit(key, value) for every entry, chunk by chunk, until it returns false; false when it did.
  template <typename Visit>
  bool visit_all(Visit&& visit) const {
    for (const auto& [chunk_code, chunk] : chunks_) {
      for (const auto& [key, value] : chunk->entries) {
        if (!visit(key, *value)) return false;
      }
    }
    return true;
  }

  // Sets each (key, value) of changes in turn, a null value removing the key (a key given twice takes the later
  // value); calls replaced(key, old value or nullptr, new value or nullptr) once per key, for the caller's running
  // sums. Each chunk changed is copied once.
  template <typename Replaced>
  void apply(std::vector<std::pair<Key, ValuePtr>> changes, Replaced&& replaced) {
    const auto order = [](const Key& key) { return std::pair(Traits::chunk(key), Traits::code(key)); };
    std::stable_sort(changes.begin(), changes.end(),
                     [&order](const auto& a, const auto& b) { return order(a.first) < order(b.first); });
    // Of a key's changes keep the last: unique keeps the first of equal neighbours, so reverse around it.
    std::reverse(changes.begin(), changes.end());
    changes.erase(std::unique(changes.begin(), changes.end(),
                              [&order](const auto& a, const auto& b) { return order(a.first) == order(b.first); }),
                  changes.end());
    std::reverse(changes.begin(), changes.end());
    std::vector<ChunkEntry> chunks;
    chunks.reserve(chunks_.size() + changes.size());
    auto old_chunk = chunks_.begin();
    auto change = changes.begin();
    const std::vector<Entry> none;
    while (change != changes.end()) {
      const std::uint64_t chunk_code = Traits::chunk(change->first);
      while (old_chunk != chunks_.end() && old_chunk->first < chunk_code) chunks.push_back(std::move(*old_chunk++));
      const bool existed = old_chunk != chunks_.end() && old_chunk->first == chunk_code;
      const std::vector<Entry>& before = existed ? old_chunk->second->entries : none;
      auto merged = std::make_shared<Chunk>();
      merged->entries.reserve(before.size() + 8);
      auto entry = before.begin();
      for (; change != changes.end() && Traits::chunk(change->first) == chunk_code; ++change) {
        const std::uint64_t code = Traits::code(change->first);
        while (entry != before.end() && Traits::code(entry->first) < code) merged->entries.push_back(*entry++);
        const bool had = entry != before.end() && Traits::code(entry->first) == code;
        replaced(change->first, had ? entry->second.get() : nullptr, change->second.get());
        size_ = size_ - (had ? 1 : 0) + (change->second ? 1 : 0);
        if (change->second) merged->entries.emplace_back(change->first, std::move(change->second));
        if (had) ++entry;
      }
      merged->entries.insert(merged->entries.end(), entry, before.end());
      if (existed) ++old_chunk;
      if (!merged->entries.empty()) chunks.emplace_back(chunk_code, std::move(merged));
    }
    while (old_chunk != chunks_.end()) chunks.push_back(std::move(*old_chunk++));
    chunks_ = std::move(chunks);
  }

  void apply(std::vector<std::pair<Key, ValuePtr>> changes) {
    apply(std::move(changes), [](const Key&, const Value*, const Value*) {});
  }

  void clear() {
    chunks_.clear();
    size_ = 0;
  }

 private:
  using Entry = std::pair<Key, ValuePtr>;
  struct Chunk {
    std::vector<Entry> entries;  // in code order
  };
  using ChunkEntry = std::pair<std::uint64_t, std::shared_ptr<const Chunk>>;

  std::vector<ChunkEntry> chunks_;  // in chunk order
  std::size_t size_ = 0;
};

}  // namespace occgeo::mapping
