#pragma once

// The track table dock: every track the map shows, one row each, sortable by start, duration,
// speed, heading, visit, confidence and the analyst's verdict, with a text filter (id, verdict,
// label, note). Selecting a row selects the track; double-clicking (or Enter) jumps to it. The
// table reads the mission and the reviews it is given; it changes nothing itself.

#include "core/mission/mission.h"

#include <QAbstractTableModel>
#include <QSortFilterProxyModel>
#include <QWidget>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

class QLineEdit;
class QLabel;
class QTableView;

namespace saker::ui {

// One row per track of the mission (row == track index).
class TrackTableModel : public QAbstractTableModel {
  Q_OBJECT

 public:
  enum Column {
    kTrack,
    kStart,
    kDuration,
    kSpeed,
    kHeading,
    kVisit,
    kConfidence,
    kVerdict,
    kLabel,
    kNote,
    kColumnCount
  };
  // The value a column sorts by (numbers as numbers).
  static constexpr int kSortRole = Qt::UserRole + 1;

  explicit TrackTableModel(QObject* parent = nullptr);
  void setMission(std::shared_ptr<const mission::Mission> mission);
  // The reviews to show (sorted by track id, as Mission::reviews); read at every paint, so call
  // reviewsChanged() after changing them.
  void setReviews(const std::vector<mission::TrackReview>* reviews);
  void reviewsChanged();

  int rowCount(const QModelIndex& parent = {}) const override;
  int columnCount(const QModelIndex& parent = {}) const override;
  QVariant data(const QModelIndex& index, int role = Qt::DisplayRole) const override;
  QVariant headerData(int section, Qt::Orientation orientation,
                      int role = Qt::DisplayRole) const override;

 private:
  const mission::TrackReview* ReviewAt(int row) const;

  std::shared_ptr<const mission::Mission> mission_;
  const std::vector<mission::TrackReview>* reviews_ = nullptr;
};

// The model's rows that the map shows and that match the text filter.
class TrackFilterModel : public QSortFilterProxyModel {
  Q_OBJECT

 public:
  explicit TrackFilterModel(QObject* parent = nullptr);
  // Whether the map shows track `index`; null: every track.
  void setShown(std::function<bool(size_t)> shown);
  void setText(const QString& text);  // case-insensitive, in id, verdict, label and note
  void refilter() { invalidateFilter(); }

 protected:
  bool filterAcceptsRow(int row, const QModelIndex& parent) const override;

 private:
  std::function<bool(size_t)> shown_;
  QString text_;
};

class TrackTable : public QWidget {
  Q_OBJECT

 public:
  explicit TrackTable(QWidget* parent = nullptr);

  void setMission(std::shared_ptr<const mission::Mission> mission);
  void setReviews(const std::vector<mission::TrackReview>* reviews);
  void reviewsChanged();
  void setShown(std::function<bool(size_t)> shown);
  void shownChanged();  // the map's filter changed
  // Selects the row of a track (and scrolls to it) without emitting trackSelected; nullopt
  // clears the selection.
  void selectTrack(std::optional<size_t> track_index);

  QTableView* view() const { return view_; }
  TrackFilterModel* filterModel() const { return proxy_; }
  QLineEdit* filterEdit() const { return filter_; }
  int rowsShown() const;
  // The track shown in row `row` of the view (sorted, filtered); nullopt past the end.
  std::optional<size_t> trackAtRow(int row) const;

 signals:
  void trackSelected(size_t track_index);   // a row chosen by the user
  void trackActivated(size_t track_index);  // double-click or Enter on a row

 private:
  void updateCount();

  TrackTableModel* model_ = nullptr;
  TrackFilterModel* proxy_ = nullptr;
  QTableView* view_ = nullptr;
  QLineEdit* filter_ = nullptr;
  QLabel* count_ = nullptr;
  bool selecting_ = false;  // selectTrack() is changing the selection
};

}  // namespace saker::ui
