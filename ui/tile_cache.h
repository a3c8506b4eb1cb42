#pragma once

// The mosaic's tiles for the GUI: read from the mission file and decoded on a worker thread (with
// its own read-only MissionStore, since a store is one SQLite connection), kept in a
// least-recently-used cache bounded in bytes, handed to the GUI thread through the queued
// tileReady signal. The GUI thread never waits on the worker: tile() only looks in the cache.

#include "core/mission/mission.h"
#include "ui/mailbox.h"

#include <QHash>
#include <QImage>
#include <QList>
#include <QObject>
#include <QSet>
#include <QString>
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <optional>

namespace saker::ui {

// One tile of the pyramid: level 0 is full resolution.
struct TileKey {
  int level = 0;
  int x = 0;
  int y = 0;
  bool operator==(const TileKey& other) const {
    return level == other.level && x == other.x && y == other.y;
  }
};

inline size_t qHash(const TileKey& key, size_t seed = 0) {
  return ::qHash((static_cast<quint64>(static_cast<uint32_t>(key.level)) << 48) ^
                     (static_cast<quint64>(static_cast<uint32_t>(key.x)) << 24) ^
                     static_cast<quint64>(static_cast<uint32_t>(key.y)),
                 seed);
}

class TileCache : public QObject {
  Q_OBJECT

 public:
  enum class State {
    kUnknown,  // never loaded (or stale after a reload): worth requesting
    kPending,  // queued or being read
    kLoaded,   // tile() has its image
    kEmpty,    // the file has no such tile (nothing covers it) or it could not be read
  };

  explicit TileCache(QObject* parent = nullptr);
  // Stops the worker after the tile it is reading (a few milliseconds); queued requests are
  // dropped.
  ~TileCache() override;

  // Shows the tiles of the mission file at `path` laid out as `pyramid`; an empty path or no
  // pyramid clears. Calling it again with the same path and pyramid reloads (after the file got
  // new tiles): the images already held stay visible until their fresh copies arrive, so the
  // view does not flash.
  void setMission(const QString& path, std::optional<mission::PyramidInfo> pyramid);
  const QString& missionPath() const { return path_; }
  const std::optional<mission::PyramidInfo>& pyramid() const { return pyramid_; }

  // The decoded tile (Format_ARGB32_Premultiplied, transparent where the mosaic has no data),
  // including a stale copy kept over a reload; null when not loaded. Never blocks.
  QImage tile(int level, int x, int y) const;
  State state(int level, int x, int y) const;

  // Queues one tile behind those already queued (ignored when loaded, queued or empty).
  void request(int level, int x, int y);
  // Replaces the queue by `tiles` (in that order, those loaded, pending or empty skipped): the
  // newest view wins, so zooming fast never leaves a backlog of tiles nobody looks at.
  void requestVisible(const QList<TileKey>& tiles);

  // The cache's size limit (default 256 MiB); least recently used tiles go first.
  void setByteBudget(qint64 bytes);
  qint64 byteBudget() const { return byte_budget_; }
  qint64 bytesUsed() const { return bytes_used_; }
  int queuedCount() const {
    return static_cast<int>(pending_.size());
  }  // requests not yet answered

 signals:
  // A requested tile was answered (loaded or found empty), on the GUI thread.
  void tileReady(int level, int x, int y);
  // The mission's tiles cannot be read (a missing or corrupt file, an undecodable tile). Sent
  // once per setMission; the message names the file.
  void failed(const QString& message);

 private:
  struct Shared;  // the request queue, shared with the worker thread
  using Deliver = std::function<void(quint64 generation, TileKey key, QImage image, QString error)>;
  static void runWorker(Shared* shared, const Deliver& deliver);
  struct Entry {
    QImage image;        // null: the tile is empty
    bool stale = false;  // from before a reload: shown, but requested again
    std::list<TileKey>::iterator lru;
  };

  // On the GUI thread: an answer from the worker for request `generation`.
  void onLoaded(quint64 generation, TileKey key, QImage image, QString error);
  void insert(const TileKey& key, QImage image);
  void touch(const Entry& entry) const;
  void evict();
  bool wanted(const TileKey& key) const;  // not loaded fresh, not empty, in the pyramid

  std::unique_ptr<Shared> shared_;
  Mailbox* mailbox_ = nullptr;  // the worker's tiles, to the GUI thread
  QString path_;
  std::optional<mission::PyramidInfo> pyramid_;
  quint64 generation_ = 0;
  bool failure_reported_ = false;
  QHash<TileKey, Entry> entries_;
  QSet<TileKey> pending_;           // sent to the worker, not answered yet
  mutable std::list<TileKey> lru_;  // front: most recently used
  qint64 byte_budget_ = static_cast<qint64>(256) << 20;
  qint64 bytes_used_ = 0;
};

}  // namespace saker::ui
