#pragma once

// The front end's checkpoints (frontend::FrontEndCheckpoint) in the mission file's checkpoint
// table, so that an interrupted job resumes rather than restarts (docs/reliability.md, "Resume";
// the record layouts are in docs/mission-file.md). Each checkpoint is one transaction: the new
// frames, key frames (with their grey images as PNG), links, breaks and finished targets are
// appended, the open targets and the state replaced.

#include "core/frontend/front_end.h"
#include "core/mission/mission_store.h"
#include "core/util/status.h"

#include <cstdint>
#include <optional>

namespace saker::pipeline {

// Writes the checkpoints of one job into `store` (open for writing; the writer does not own it).
class CheckpointWriter {
 public:
  // `resumed`: the checkpoint the job resumed from, which the file holds already.
  explicit CheckpointWriter(mission::MissionStore* store,
                            const frontend::FrontEndCheckpoint* resumed = nullptr);

  // Appends one delivery of RunFrontEnd (FrontEndOptions::on_checkpoint), in one transaction.
  Status Write(const frontend::FrontEndCheckpoint& delivery);

 private:
  mission::MissionStore* store_;
  int64_t links_ = 0, breaks_ = 0, targets_ = 0, change_targets_ = 0;  // records written
};

// The checkpoint the file holds, merged, or nullopt when it holds none. InvalidData naming the
// file, the record and the problem when a record is malformed or the records do not fit together.
StatusOr<std::optional<frontend::FrontEndCheckpoint>> ReadCheckpoint(
    const mission::MissionStore& store);

// What `saker-cli info` and the GUI say about a checkpoint, without decoding its images.
struct CheckpointState {
  int64_t through_frame = -1;  // the front end's work is kept up to this frame
  bool complete = false;       // the front end finished; a later stage was interrupted
  int64_t key_frames = 0;
};
// Nothing when the file holds no checkpoint; InvalidData when its state record is malformed.
StatusOr<std::optional<CheckpointState>> ReadCheckpointState(const mission::MissionStore& store);

}  // namespace saker::pipeline
