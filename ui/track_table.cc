#include "ui/track_table.h"

#include <QAbstractItemView>
#include <QFont>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QItemSelectionModel>
#include <QKeyEvent>
#include <QLabel>
#include <QLineEdit>
#include <QPalette>
#include <QSignalBlocker>
#include <QTableView>
#include <QVBoxLayout>
#include <algorithm>
#include <cmath>
#include <utility>

namespace saker::ui {
namespace {

QString FromStd(const std::string& s) { return QString::fromStdString(s); }

// "1:05.2": minutes and seconds in the video.
QString Clock(double seconds) {
  if (!std::isfinite(seconds)) return QStringLiteral("–");
  const double s = std::max(seconds, 0.0);
  const int minutes = static_cast<int>(s / 60);
  return QStringLiteral("%1:%2").arg(minutes).arg(s - 60.0 * minutes, 4, 'f', 1, QLatin1Char('0'));
}

QString VerdictText(mission::Verdict verdict) {
  switch (verdict) {
    case mission::Verdict::kConfirmed:
      return TrackTableModel::tr("Confirmed");
    case mission::Verdict::kFalse:
      return TrackTableModel::tr("False");
    case mission::Verdict::kNone:
      break;
  }
  return {};
}

QString LabelText(mission::TargetLabel label) {
  switch (label) {
    case mission::TargetLabel::kVehicle:
      return TrackTableModel::tr("Vehicle");
    case mission::TargetLabel::kPerson:
      return TrackTableModel::tr("Person");
    case mission::TargetLabel::kOther:
      return TrackTableModel::tr("Other");
    case mission::TargetLabel::kNone:
      break;
  }
  return {};
}

}  // namespace

// ------------------------------------------------------------------------------------------------
// TrackTableModel

TrackTableModel::TrackTableModel(QObject* parent) : QAbstractTableModel(parent) {}

void TrackTableModel::setMission(std::shared_ptr<const mission::Mission> mission) {
  beginResetModel();
  mission_ = std::move(mission);
  endResetModel();
}

void TrackTableModel::setReviews(const std::vector<mission::TrackReview>* reviews) {
  reviews_ = reviews;
  reviewsChanged();
}

void TrackTableModel::reviewsChanged() {
  if (rowCount() == 0) return;
  emit dataChanged(index(0, 0), index(rowCount() - 1, kColumnCount - 1));
}

int TrackTableModel::rowCount(const QModelIndex& parent) const {
  if (parent.isValid() || !mission_) return 0;
  return static_cast<int>(mission_->tracks.size());
}

int TrackTableModel::columnCount(const QModelIndex& parent) const {
  return parent.isValid() ? 0 : kColumnCount;
}

const mission::TrackReview* TrackTableModel::ReviewAt(int row) const {
  if (reviews_ == nullptr || !mission_) return nullptr;
  return mission::FindReview(*reviews_, mission_->tracks[static_cast<size_t>(row)].id);
}

QVariant TrackTableModel::data(const QModelIndex& index, int role) const {
  if (!index.isValid() || !mission_ || index.row() >= rowCount()) return {};
  const mission::ActivityTrack& t = mission_->tracks[static_cast<size_t>(index.row())];
  const mission::TrackReview* review = ReviewAt(index.row());
  const bool geo = mission_->map.geo_referenced;
  const double speed = geo && t.speed_mps ? *t.speed_mps : t.speed;
  const auto column = static_cast<Column>(index.column());
  if (role == Qt::DisplayRole) {
    switch (column) {
      case kTrack:
        return QString::number(t.id);
      case kStart:
        return Clock(t.start_s);
      case kDuration:
        return QString::number(t.end_s - t.start_s, 'f', 1);
      case kSpeed:
        return std::isfinite(speed) ? QString::number(speed, 'f', 1) : QStringLiteral("–");
      case kHeading:
        return QStringLiteral("%1°").arg(std::lround(t.heading_deg) % 360);
      case kVisit:
        return t.visit;
      case kConfidence:
        return t.confidence ? QString::number(*t.confidence, 'f', 2) : tr("unknown");
      case kVerdict:
        return review ? VerdictText(review->verdict) : QString();
      case kLabel:
        return review ? LabelText(review->label) : QString();
      case kNote:
        return review ? FromStd(review->note).section(QLatin1Char('\n'), 0, 0) : QString();
      case kColumnCount:
        break;
    }
    return {};
  }
  if (role == kSortRole) {
    switch (column) {
      case kTrack:
        return static_cast<qlonglong>(t.id);
      case kStart:
        return t.start_s;
      case kDuration:
        return t.end_s - t.start_s;
      case kSpeed:
        return std::isfinite(speed) ? speed : -1.0;
      case kHeading:
        return t.heading_deg;
      case kVisit:
        return t.visit;
      case kConfidence:
        return t.confidence.value_or(-1.0);
      case kVerdict:
        return review ? static_cast<int>(review->verdict) : 0;
      case kLabel:
        return review ? LabelText(review->label) : QString();
      case kNote:
        return review ? FromStd(review->note) : QString();
      case kColumnCount:
        break;
    }
    return {};
  }
  if (role == Qt::ToolTipRole && column == kNote && review && !review->note.empty()) {
    return FromStd(review->note);
  }
  if (role == Qt::TextAlignmentRole && column != kNote && column != kVerdict && column != kLabel) {
    return QVariant::fromValue(Qt::AlignRight | Qt::AlignVCenter);
  }
  if (review && review->verdict == mission::Verdict::kFalse) {
    // A false track (shown only when asked for): greyed and struck through.
    if (role == Qt::ForegroundRole) return QPalette().brush(QPalette::Disabled, QPalette::Text);
    if (role == Qt::FontRole) {
      QFont font;
      font.setStrikeOut(true);
      return font;
    }
  }
  return {};
}

QVariant TrackTableModel::headerData(int section, Qt::Orientation orientation, int role) const {
  if (orientation != Qt::Horizontal || role != Qt::DisplayRole) return {};
  const bool geo = mission_ && mission_->map.geo_referenced;
  switch (static_cast<Column>(section)) {
    case kTrack:
      return tr("Track");
    case kStart:
      return tr("Start");
    case kDuration:
      return tr("Duration (s)");
    case kSpeed:
      return geo ? tr("Speed (m/s)") : tr("Speed (px/s)");
    case kHeading:
      return tr("Heading");
    case kVisit:
      return tr("Visit");
    case kConfidence:
      return tr("Confidence");
    case kVerdict:
      return tr("Verdict");
    case kLabel:
      return tr("Label");
    case kNote:
      return tr("Note");
    case kColumnCount:
      break;
  }
  return {};
}

// ------------------------------------------------------------------------------------------------
// TrackFilterModel

TrackFilterModel::TrackFilterModel(QObject* parent) : QSortFilterProxyModel(parent) {
  setSortRole(TrackTableModel::kSortRole);
}

void TrackFilterModel::setShown(std::function<bool(size_t)> shown) {
  shown_ = std::move(shown);
  invalidateFilter();
}

void TrackFilterModel::setText(const QString& text) {
  text_ = text.trimmed();
  invalidateFilter();
}

bool TrackFilterModel::filterAcceptsRow(int row, const QModelIndex& parent) const {
  if (shown_ && !shown_(static_cast<size_t>(row))) return false;
  if (text_.isEmpty()) return true;
  for (const int column : {TrackTableModel::kTrack, TrackTableModel::kVerdict,
                           TrackTableModel::kLabel, TrackTableModel::kNote}) {
    const QModelIndex index = sourceModel()->index(row, column, parent);
    const QString text = column == TrackTableModel::kNote
                             ? sourceModel()->data(index, TrackTableModel::kSortRole).toString()
                             : sourceModel()->data(index).toString();
    if (text.contains(text_, Qt::CaseInsensitive)) return true;
  }
  return false;
}

// ------------------------------------------------------------------------------------------------
// TrackTable

namespace {

// Enter on a row activates it, as a double-click does (QTableView only does so on some styles).
class TrackView : public QTableView {
 public:
  using QTableView::QTableView;

 protected:
  void keyPressEvent(QKeyEvent* event) override {
    if ((event->key() == Qt::Key_Return || event->key() == Qt::Key_Enter) &&
        currentIndex().isValid()) {
      emit activated(currentIndex());
      event->accept();
      return;
    }
    QTableView::keyPressEvent(event);
  }
};

}  // namespace

TrackTable::TrackTable(QWidget* parent) : QWidget(parent) {
  model_ = new TrackTableModel(this);
  proxy_ = new TrackFilterModel(this);
  proxy_->setSourceModel(model_);
  view_ = new TrackView(this);
  view_->setObjectName(QStringLiteral("trackTableView"));
  view_->setModel(proxy_);
  view_->setSortingEnabled(true);
  view_->sortByColumn(TrackTableModel::kStart, Qt::AscendingOrder);
  view_->setSelectionBehavior(QAbstractItemView::SelectRows);
  view_->setSelectionMode(QAbstractItemView::SingleSelection);
  view_->setEditTriggers(QAbstractItemView::NoEditTriggers);
  view_->setAlternatingRowColors(true);
  view_->verticalHeader()->hide();
  view_->verticalHeader()->setDefaultSectionSize(view_->fontMetrics().height() + 6);
  view_->horizontalHeader()->setStretchLastSection(true);
  view_->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  view_->horizontalHeader()->setSectionResizeMode(TrackTableModel::kNote, QHeaderView::Stretch);

  filter_ = new QLineEdit(this);
  filter_->setObjectName(QStringLiteral("trackFilter"));
  filter_->setPlaceholderText(tr("Filter: track, verdict, label or note"));
  filter_->setClearButtonEnabled(true);
  count_ = new QLabel(this);
  count_->setObjectName(QStringLiteral("trackTableCount"));

  auto* top = new QHBoxLayout();
  top->addWidget(filter_, 1);
  top->addWidget(count_);
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(4, 4, 4, 4);
  layout->addLayout(top);
  layout->addWidget(view_);

  connect(filter_, &QLineEdit::textChanged, this, [this](const QString& text) {
    const QSignalBlocker quiet(view_->selectionModel());
    proxy_->setText(text);
    updateCount();
  });
  connect(view_->selectionModel(), &QItemSelectionModel::currentRowChanged, this,
          [this](const QModelIndex& current) {
            if (selecting_ || !current.isValid()) return;
            emit trackSelected(static_cast<size_t>(proxy_->mapToSource(current).row()));
          });
  connect(view_, &QAbstractItemView::activated, this, [this](const QModelIndex& index) {
    if (index.isValid()) {
      emit trackActivated(static_cast<size_t>(proxy_->mapToSource(index).row()));
    }
  });
  updateCount();
}

// Rows that come and go (a new mission, a filter) move the view's current row; that is not the
// user choosing a track.
void TrackTable::setMission(std::shared_ptr<const mission::Mission> mission) {
  const QSignalBlocker quiet(view_->selectionModel());
  model_->setMission(std::move(mission));
  updateCount();
}

void TrackTable::setReviews(const std::vector<mission::TrackReview>* reviews) {
  model_->setReviews(reviews);
}

void TrackTable::reviewsChanged() {
  const QSignalBlocker quiet(view_->selectionModel());
  model_->reviewsChanged();
  proxy_->refilter();
  updateCount();
}

void TrackTable::setShown(std::function<bool(size_t)> shown) {
  proxy_->setShown(std::move(shown));
  updateCount();
}

void TrackTable::shownChanged() {
  const QSignalBlocker quiet(view_->selectionModel());
  proxy_->refilter();
  updateCount();
}

void TrackTable::selectTrack(std::optional<size_t> track_index) {
  selecting_ = true;
  QModelIndex row;
  if (track_index && static_cast<int>(*track_index) < model_->rowCount()) {
    row = proxy_->mapFromSource(model_->index(static_cast<int>(*track_index), 0));
  }
  if (row.isValid()) {
    view_->selectionModel()->setCurrentIndex(
        row, QItemSelectionModel::ClearAndSelect | QItemSelectionModel::Rows);
    view_->scrollTo(row);
  } else {
    view_->selectionModel()->clearSelection();
    view_->selectionModel()->setCurrentIndex(QModelIndex(), QItemSelectionModel::NoUpdate);
  }
  selecting_ = false;
}

int TrackTable::rowsShown() const { return proxy_->rowCount(); }

std::optional<size_t> TrackTable::trackAtRow(int row) const {
  if (row < 0 || row >= proxy_->rowCount()) return std::nullopt;
  return static_cast<size_t>(proxy_->mapToSource(proxy_->index(row, 0)).row());
}

void TrackTable::updateCount() {
  count_->setText(tr("%1 of %2").arg(proxy_->rowCount()).arg(model_->rowCount()));
}

}  // namespace saker::ui
