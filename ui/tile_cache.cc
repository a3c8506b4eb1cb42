#include "ui/tile_cache.h"

#include "core/mission/mission_store.h"
#include "core/tiles/pyramid.h"
#include "core/util/status.h"

#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <new>
#include <string>
#include <thread>
#include <utility>

namespace saker::ui {

namespace {

bool SamePyramid(const std::optional<mission::PyramidInfo>& a,
                 const std::optional<mission::PyramidInfo>& b) {
  if (a.has_value() != b.has_value()) return false;
  if (!a) return true;
  return a->tile_size == b->tile_size && a->levels == b->levels && a->width == b->width &&
         a->height == b->height && a->map_origin == b->map_origin && a->step_x == b->step_x &&
         a->step_y == b->step_y;
}

// QImage's ARGB32 is one 32-bit value per pixel (BGRA in memory only on little-endian machines):
// packing each pixel is portable, and cheap next to the PNG decode.
// A null image when Qt cannot allocate it (the caller reports that).
QImage ImageFromBgra(const cv::Mat& bgra) {
  QImage image(bgra.cols, bgra.rows, QImage::Format_ARGB32);
  if (image.isNull()) return image;
  for (int row = 0; row < bgra.rows; ++row) {
    const uint8_t* in = bgra.ptr<uint8_t>(row);
    auto* out = reinterpret_cast<QRgb*>(image.scanLine(row));
    for (int col = 0; col < bgra.cols; ++col, in += 4) out[col] = qRgba(in[2], in[1], in[0], in[3]);
  }
  // Premultiplied is what the raster paint engine blends without converting on every paint.
  return image.convertToFormat(QImage::Format_ARGB32_Premultiplied);
}

// Reads and decodes one tile into `image` (null when the store has none); the error, or empty.
// Never throws: an exception here would end the GUI (the worker is a std::thread).
std::string LoadTile(const mission::MissionStore& store, const TileKey& key, int tile_size,
                     QImage* image) {
  try {
    auto bytes = store.ReadTile(key.level, key.x, key.y);
    if (!bytes.ok()) return bytes.status().message();
    if (!bytes->has_value()) return {};
    auto decoded = tiles::DecodeTile(**bytes, tile_size);
    if (!decoded.ok()) return decoded.status().message();
    *image = ImageFromBgra(*decoded);
    if (image->isNull()) throw std::bad_alloc();  // Qt could not allocate it
    return {};
  } catch (...) {
    *image = QImage();
    return StatusFromCurrentException("").message();
  }
}

// Bytes an entry counts against the budget; empty tiles count a little, so that the bookkeeping
// of a long session stays bounded too.
qint64 Cost(const QImage& image) { return image.sizeInBytes() + 64; }

}  // namespace

// The queue between the GUI thread and the worker. Everything here is guarded by `mutex`.
struct TileCache::Shared {
  struct Request {
    TileKey key;
    quint64 generation = 0;
  };

  std::mutex mutex;
  std::condition_variable wake;
  bool stop = false;
  std::string path;        // the mission file of `generation`
  int tile_size = 0;       // its pyramid's
  quint64 generation = 0;  // bumped by every setMission
  std::deque<Request> queue;
  std::optional<Request> busy;  // being read now (not in `queue`)
  std::thread thread;
};

// The worker: one read-only store per mission generation, opened on this thread.
void TileCache::runWorker(Shared* shared, const Deliver& deliver) {
  std::unique_ptr<mission::MissionStore> store;
  std::optional<quint64> store_generation;
  std::string open_error;
  for (;;) {
    TileKey key;
    quint64 generation = 0;
    std::string path;
    int tile_size = 0;
    {
      std::unique_lock lock(shared->mutex);
      shared->wake.wait(lock, [&] { return shared->stop || !shared->queue.empty(); });
      if (shared->stop) return;
      const Shared::Request request = shared->queue.front();
      shared->queue.pop_front();
      key = request.key;
      generation = request.generation;
      if (generation != shared->generation) continue;  // queued before a setMission
      shared->busy = request;
      path = shared->path;
      tile_size = shared->tile_size;
    }
    if (store_generation != generation) {
      // A reload opens the file afresh, so new tiles and a replaced file are both seen.
      store.reset();
      open_error.clear();
      auto opened = mission::MissionStore::Open(path, mission::OpenMode::kReadOnly);
      if (opened.ok()) {
        store = std::move(opened).value();
      } else {
        open_error = opened.status().message();
      }
      store_generation = generation;
    }
    QImage image;
    std::string error = open_error;
    if (store) error = LoadTile(*store, key, tile_size, &image);
    if (!error.empty() && error.find(path) == std::string::npos) {
      error = path + ": tile " + std::to_string(key.level) + "/" + std::to_string(key.x) + "/" +
              std::to_string(key.y) + ": " + error;
    }
    std::lock_guard lock(shared->mutex);
    shared->busy.reset();
    if (shared->stop) return;
    deliver(generation, key, std::move(image), QString::fromStdString(error));
  }
}

TileCache::TileCache(QObject* parent)
    : QObject(parent), shared_(std::make_unique<Shared>()), mailbox_(new Mailbox(this)) {
  // The worker posts each answer to this object's thread; the destructor joins the worker before
  // the mailbox goes, and Qt drops events posted to a deleted object, so no answer outlives us.
  auto deliver = [this](quint64 generation, TileKey key, QImage image, QString error) {
    mailbox_->post(
        [this, generation, key, image = std::move(image), error = std::move(error)]() mutable {
          onLoaded(generation, key, std::move(image), std::move(error));
        });
  };
  Shared* shared = shared_.get();
  shared_->thread = std::thread([shared, deliver] { runWorker(shared, deliver); });
}

TileCache::~TileCache() {
  {
    std::lock_guard lock(shared_->mutex);
    shared_->stop = true;
    shared_->queue.clear();
  }
  shared_->wake.notify_all();
  shared_->thread.join();
}

void TileCache::setMission(const QString& path, std::optional<mission::PyramidInfo> pyramid) {
  if (path.isEmpty() || !pyramid || pyramid->levels <= 0 || pyramid->tile_size <= 0) {
    pyramid.reset();
  }
  const bool reload = !path.isEmpty() && path == path_ && SamePyramid(pyramid, pyramid_);
  path_ = pyramid ? path : QString();
  pyramid_ = pyramid;
  ++generation_;
  failure_reported_ = false;
  pending_.clear();
  {
    std::lock_guard lock(shared_->mutex);
    shared_->generation = generation_;
    shared_->path = path_.toStdString();
    shared_->tile_size = pyramid_ ? pyramid_->tile_size : 0;
    shared_->queue.clear();
  }
  if (reload) {
    // Keep what is shown until the fresh copy arrives; empty entries are simply asked again.
    for (auto it = entries_.begin(); it != entries_.end();) {
      if (it->image.isNull()) {
        bytes_used_ -= Cost(it->image);
        lru_.erase(it->lru);
        it = entries_.erase(it);
      } else {
        it->stale = true;
        ++it;
      }
    }
  } else {
    entries_.clear();
    lru_.clear();
    bytes_used_ = 0;
  }
}

QImage TileCache::tile(int level, int x, int y) const {
  const auto it = entries_.constFind(TileKey{level, x, y});
  if (it == entries_.cend()) return {};
  touch(*it);
  return it->image;
}

TileCache::State TileCache::state(int level, int x, int y) const {
  const TileKey key{level, x, y};
  if (pending_.contains(key)) return State::kPending;
  const auto it = entries_.constFind(key);
  if (it == entries_.cend() || it->stale) return State::kUnknown;
  return it->image.isNull() ? State::kEmpty : State::kLoaded;
}

bool TileCache::wanted(const TileKey& key) const {
  if (!pyramid_ || key.level < 0 || key.level >= pyramid_->levels || key.x < 0 || key.y < 0) {
    return false;
  }
  const int64_t span = static_cast<int64_t>(pyramid_->tile_size) << key.level;
  if (key.x >= (pyramid_->width + span - 1) / span ||
      key.y >= (pyramid_->height + span - 1) / span) {
    return false;
  }
  const auto it = entries_.constFind(key);
  return it == entries_.cend() || it->stale;
}

void TileCache::request(int level, int x, int y) {
  const TileKey key{level, x, y};
  if (!wanted(key) || pending_.contains(key)) return;
  pending_.insert(key);
  {
    std::lock_guard lock(shared_->mutex);
    shared_->queue.push_back({key, generation_});
  }
  shared_->wake.notify_one();
}

void TileCache::requestVisible(const QList<TileKey>& tiles) {
  {
    std::lock_guard lock(shared_->mutex);
    shared_->queue.clear();
    pending_.clear();
    if (shared_->busy && shared_->busy->generation == generation_) {
      pending_.insert(shared_->busy->key);
    }
    for (const TileKey& key : tiles) {
      if (!wanted(key) || pending_.contains(key)) continue;
      pending_.insert(key);
      shared_->queue.push_back({key, generation_});
    }
  }
  shared_->wake.notify_one();
}

void TileCache::setByteBudget(qint64 bytes) {
  byte_budget_ = std::max<qint64>(bytes, 0);
  evict();
}

void TileCache::onLoaded(quint64 generation, TileKey key, QImage image, QString error) {
  if (generation != generation_) return;  // answer for a mission no longer shown
  pending_.remove(key);
  if (!error.isEmpty() && !failure_reported_) {
    failure_reported_ = true;
    emit failed(error);
  }
  // An unreadable tile counts as empty: asking again would only repeat the error.
  insert(key, std::move(image));
  emit tileReady(key.level, key.x, key.y);
}

void TileCache::insert(const TileKey& key, QImage image) {
  auto it = entries_.find(key);
  if (it != entries_.end()) {
    bytes_used_ -= Cost(it->image);
    lru_.erase(it->lru);
    entries_.erase(it);
  }
  lru_.push_front(key);
  Entry entry;
  entry.image = std::move(image);
  entry.lru = lru_.begin();
  bytes_used_ += Cost(entry.image);
  entries_.insert(key, std::move(entry));
  evict();
}

void TileCache::touch(const Entry& entry) const { lru_.splice(lru_.begin(), lru_, entry.lru); }

void TileCache::evict() {
  while (bytes_used_ > byte_budget_ && !lru_.empty()) {
    const TileKey key = lru_.back();
    lru_.pop_back();
    const auto it = entries_.find(key);
    if (it == entries_.end()) continue;
    bytes_used_ -= Cost(it->image);
    entries_.erase(it);
  }
}

}  // namespace saker::ui
