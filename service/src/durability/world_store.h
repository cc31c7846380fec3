#pragma once
// Where a world's maps live on disk, and how they come back: a snapshot folder per world
// (<data_dir>/worlds/<name>/: grid.pgm + grid.yaml, octomap.bt, ptem.bin (the PTEM clusters, bit for bit),
// snapshot.yaml naming the last journal record it
// holds) and a journal per world (<data_dir>/journal/<name>.journal) of what was accepted since.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "journal.h"

namespace occgeo::service {
class ServerCore;
class World;
struct ServerConfig;
}  // namespace occgeo::service

namespace occgeo::service::durability {

[[nodiscard]] std::filesystem::path world_snapshot_dir(const std::filesystem::path& data_dir, const std::string& world);
[[nodiscard]] std::filesystem::path world_journal_file(const std::filesystem::path& data_dir, const std::string& world);

// The journal of a world under the configured policy; `next_lsn` continues what the data directory holds, whose
// snapshot holds the records up to `snapshot_lsn`.
[[nodiscard]] std::shared_ptr<WorldJournal> make_world_journal(const ServerConfig& config, metrics::Registry& metrics,
                                                               const std::string& world, std::uint64_t next_lsn = 1,
                                                               std::uint64_t snapshot_lsn = 0);

// Restores every world of the data directory: its snapshot, then the journal records after it, replayed through the
// same insertion code ingest runs. A torn last record is cut off with a warning; damage in the middle of a journal, or
// a damaged snapshot, throws with the file's name. Each world gets its journal attached. Call before any work reaches
// the worlds' strands.
void restore_worlds(ServerCore& core);

// Writes the world's snapshot (to a temporary folder renamed into place) and then empties its journal, which the
// snapshot now holds. Call on the world's strand, or once the ingest pool is drained. Returns false (after logging)
// when the snapshot could not be written; the journal is then left whole.
bool snapshot_world(ServerCore& core, World& world);

// Snapshots the world on its strand if its journal holds records the last snapshot does not.
void snapshot_world_if_changed(ServerCore& core, const std::shared_ptr<World>& world);

}  // namespace occgeo::service::durability
