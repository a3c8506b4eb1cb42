#pragma once

// Change detection: the Visual MTI's second look, for movers too small for feature tracks.
//
// From 400 m a walker is two or three pixels across and moves a quarter of a pixel per frame. The
// corners found on it are few, and the Lucas-Kanade window (eleven pixels) is dominated by the
// ground around it, so the feature tracks (motion_segmentation.h) follow the footpath instead. Over
// a longer baseline, though, the walker has moved its own size, and the image shows it: once an
// earlier frame is warped onto the current one with the ground motion, the ground cancels and the
// walker leaves a difference where it is now and one where it was.
//
// ChangeDetector compares a frame with the frames `baseline_s` before and after it, both warped
// onto it by the chained frame-to-frame ground homographies (so its answer comes that late). A
// pixel has *changed* when both differences are significant and have the same sign: the mover is
// there in the middle frame and in neither of the others. Where it was before or will be after,
// only one of the two differs, so it leaves no ghost, even when it is longer than the distance it
// moves (comparing with two earlier frames would leave one behind a slow car). "Significant" is
// relative to the noise and to the local gradient times an allowance for misregistration (an edge
// off by a tenth of a pixel differs too), after matching the earlier frames' mean grey level (gain
// drift). Changed pixels are grouped into blobs.
//
// Two uses: ChangeFrame::ChangedNear() lets a feature target be checked against the image (a corner
// sliding along a road marking has no change under it; a car or a walker does), and BlobTracker
// follows small blobs over time. Like the feature segmentation, one frame never makes a target: a
// blob track is confirmed only after it has moved steadily, in a straight enough line, for long
// enough.

#include "core/track/image_geometry.h"
#include "core/track/target_tracks.h"
#include "core/util/byte_io.h"
#include "core/util/status.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <array>
#include <deque>
#include <optional>
#include <vector>

namespace saker::track {

struct ChangeOptions {
  bool enabled = true;
  // A frame is compared with those this long before and after [1 frame, at most 100 frames]: the
  // default is the 12 frames tuned at 25 frames a second.
  double baseline_s = 0.48;
  // The targets' change evidence (ChangedNear) also compares the frame with the one this long
  // before it and the one a baseline after it [1 frame, at most 100 frames; 0: off; never with
  // `one_sided_edges`]. A walker and its shadow make one dark streak along its motion, and a
  // streak of length L moving d a baseline leaves no pixel that differs from both frames a
  // baseline away unless L < 2d; the frame this long before it shows the ground the streak's rear
  // has left. The answer is not later (the frame after is the baseline's), and the pair's changes
  // are evidence only, never blobs.
  double evidence_baseline_s = 1.4;
  // Where the frames before and after do not both see the centre frame's ground (the edges of a
  // moving camera's view), also compare it with the two frames a baseline and two baselines
  // before it, or the two after it. Sound only for movers that leave their own outline within
  // one baseline (at 1-4 frames a second every car and walker does; a slower one leaves a ghost
  // where it was): the low-frame-rate mode turns it on, where the ground moves a sixth of the
  // frame between frames and the edges are a third of the image. The answer then comes two
  // baselines late. Parallax (a roof seen from three places) differs from the centre frame with
  // opposite signs before and after it, which the centred test rejects, but often with one sign
  // on one side: so the one-sided comparisons are made only where they gain much, when the
  // centred ones leave at least `one_sided_min_uncovered` of the frame unseen (a fast pan, not
  // the corners an orbit's rotation leaves).
  bool one_sided_edges = false;
  double one_sided_min_uncovered = 0.1;
  int processing_width = 960;  // on a copy this wide (never enlarged); 0 = full resolution
  // ... or wider, up to the full width, where the metadata gives the ground's scale and a
  // processing pixel at the image centre would span more ground than this: a walker (half a
  // metre) stays a pixel or two (ProcessingWidth). 0: processing_width alone.
  double max_processing_gsd_m = 0.3;
  double noise_grey = 2.5;  // grey-level noise of one pixel's difference (sensor, compression)
  double threshold = 4;     // a difference above this many times its noise is significant
  // Misregistration allowed: the local gradient times this is added to the noise. Clean video
  // measures 0.12-0.13 px (times `measured_registration_multiple`, just under this). 0.3 until
  // session 33: a walker a pixel or two across on coarse ground (0.3-0.4 m a pixel) changes the
  // frame by less than the edges round it; 0.2 found more of them (tuning seeds, docs/accuracy.md).
  // The low-frame-rate mode keeps 0.3 (LowFrameRateOptions::registration_px).
  double registration_px = 0.2;
  // The misregistration allowance of clean video (the fixed one until session 33): an answer's
  // allowances count as raised by the video's noise (ChangeFrame::allowances_raised) above it or
  // above `noise_grey`, and the blob tracks' noise scale is the answer's allowance over it.
  double clean_registration_px = 0.3;
  // Changes this close to the edge of a warped frame are ignored (processing pixels): linear
  // interpolation there mixes in the black outside it. More hides walkers at the image's edge.
  int border_px = 2;
  // Both allowances follow the video. A low bit rate (the codec's blocks and smoothing) makes
  // registered frames differ by several grey levels on flat ground and by most of an edge's
  // contrast on texture, and the allowances above, tuned on clean video, then mark the ground
  // itself as changed. So every centre frame measures its differences with the frames a baseline
  // before and after it, on a sparse grid: the sensor noise as the robust spread (1.4826 times the
  // median absolute value) where that frame is flat (gradient below 3 grey levels a pixel), the
  // misregistration as the spread of the difference over the gradient where it is steep (above
  // 15); the smaller of the two sides counts. The medians of those over the frames held (or the
  // centre's own, when larger), times these multiples, replace `noise_grey` and `registration_px`
  // where larger. Clean simulated video measures 1.2-1.5 grey levels and 0.12-0.13 px, so the
  // fixed allowances stand; CRF 38 measures 2.6-3.1 and 0.5-1.0. 0: off.
  double measured_noise_multiple = 1;
  double measured_registration_multiple = 1.5;
  // Sharpness matched before comparing, as difference imaging matches point spread functions: a
  // frame sharper than both its neighbours (focus, a renderer's level of detail) differs from
  // them with one sign on every peak of its texture, which no allowance separates from a walker.
  // When the centre frame's mean squared gradient and that of the centred pair's frame closest
  // to it differ by more than this ratio, the sharper of the two is blurred (Gaussian) until they
  // match. Registered frames differ by up to about 1.3 from interpolation alone. 0: off.
  double sharpness_match_ratio = 1.5;
  int min_area_px = 1;  // blob size, processing pixels
  // The largest blob: at 0.2 m a pixel a car is ~110 processing pixels, a lorry ~400. A car
  // without texture (a black car on dark asphalt) has no corners for the feature tracks, and its
  // blob is all there is of it; until session 29 blobs were kept up to 80 pixels at video rates,
  // cars being left to the feature tracks (docs/front-end.md).
  int max_area_px = 600;
  double min_contrast_grey = 12;  // the strongest change in a blob, at least
  Status Validate() const;
  // The processing copy's width for frames of `size` whose ground's scale is `scale` (nullptr:
  // unknown): processing_width, widened to keep a processing pixel at the image centre within
  // max_processing_gsd_m, never beyond the frame's width.
  int ProcessingWidth(const cv::Size& size, const GroundScale* scale) const;
};

// A group of changed pixels in the latest frame.
struct ChangeBlob {
  Eigen::Vector2d position{0, 0};  // change-weighted centroid, full-resolution pixels
  Eigen::Vector2d box_min{0, 0}, box_max{0, 0};
  int area_px = 0;      // processing pixels
  double contrast = 0;  // strongest change, grey levels (negative: darker than before)
};

// What the change detector found for one frame. Self-contained: it holds its own copies of the
// small masks, so it stays valid after the detector moves on and can be handed to another thread
// (the front end runs the detector on a thread of its own and applies its answers later).
struct ChangeFrame {
  int64_t frame = -1;  // the frame compared (the centre frame); -1: no answer (too early in a
                       // segment, a degenerate motion, turned off)
  std::vector<ChangeBlob> blobs;
  Eigen::Matrix3d frame_motion = Eigen::Matrix3d::Identity();  // ground motion into `frame` from
                                                               // the frame before (full resolution)
  cv::Mat changed;  // CV_8U, processing size: non-zero where `frame` changed
  // The same from the evidence pair (ChangeOptions::evidence_baseline_s; empty without it):
  // evidence under the targets only, never blobs.
  cv::Mat evidence_changed;
  cv::Mat valid;     // CV_8U, processing size: non-zero where it could be compared
  double scale = 1;  // full-resolution pixels per processing pixel
  // The allowances the answer was made with (ChangeOptions: the fixed ones, or larger where the
  // video's measured noise asks for it).
  double noise_grey = 0, registration_px = 0;
  // The video's noise raised them: the grey-level noise above ChangeOptions::noise_grey or the
  // misregistration above ChangeOptions::clean_registration_px.
  bool allowances_raised = false;
  bool answered() const { return frame >= 0; }
  // Whether a changed pixel (of either mask) lies within `radius_px` (full resolution) of `p`.
  bool ChangedNear(const Eigen::Vector2d& p, double radius_px) const;
  // Whether `frame` could be compared at `p` (inside the overlap of the three frames).
  bool Compared(const Eigen::Vector2d& p) const;
};

class ChangeDetector {
 public:
  ChangeDetector(const ChangeOptions& options, FrameRate rate);

  // The baselines at `rate`, in frames: the short one, then the evidence baseline when it is
  // longer (and not with `one_sided_edges`).
  static std::vector<int> BaselineFrames(const ChangeOptions& options, FrameRate rate);
  // How many frames the answer comes late: the baseline, or two with `one_sided_edges`.
  static int LagFrames(const ChangeOptions& options, FrameRate rate);
  // How many frames the detector holds: the lag after the centre frame and the lag or the
  // evidence baseline, the longer, before it.
  static int HistoryFrames(const ChangeOptions& options, FrameRate rate);

  // One frame (8-bit grey, full resolution; frame indices increase). `current_from_previous` is
  // the ground motion since the previous frame in full-resolution pixels; nullopt when unknown
  // (the first frame of a chain segment): the comparison then starts again. The comparison is
  // centred: the answer belongs to the frame LagFrames() back (ChangeFrame::frame), compared with
  // the frames a baseline before and after it (and, with `one_sided_edges`, where those do not
  // both see it, with the two frames on the side that does; for the evidence, with the frame an
  // evidence baseline before it once the segment reaches back that far); no answer (frame -1)
  // while the segment is shorter than twice LagFrames().
  ChangeFrame Process(int64_t frame, const cv::Mat& grey,
                      const std::optional<Eigen::Matrix3d>& current_from_previous);
  void Reset();

 private:
  struct Entry {
    int64_t frame = 0;
    cv::Mat grey;                                                // processing size
    Eigen::Matrix3d motion = Eigen::Matrix3d::Identity();        // from the previous frame
    Eigen::Matrix3d small_motion = Eigen::Matrix3d::Identity();  // the same, processing pixels
    // What the frame's differences with the centred pair measured when it was the centre, the
    // smaller of the two (ChangeOptions::measured_noise_multiple); negative: not measured.
    float noise = -1, registration = -1;
  };
  struct Other {  // a frame before or after the centre, warped onto it
    cv::Mat warped, cover;
    float gain = 1;
    // The registration allowance's multiple: 2 for the farther frame of a one-sided pair (twice
    // the time, twice the parallax and drift of the chained motion), else 1.
    float allowance = 1;
  };
  Eigen::Vector2d ToFull(double x, double y) const;
  // The steps of Process(), in order.
  void SetFrameSize(const cv::Size& size);  // a new frame size: processing size, scale, history
  // Appends the frame at processing size, dropping the oldest beyond `capacity` frames.
  void Remember(int64_t frame, const cv::Mat& grey,
                const std::optional<Eigen::Matrix3d>& current_from_previous, size_t capacity);
  bool Warp(size_t index, size_t centre, Other* other, const cv::Mat* only_outside = nullptr);
  // Blurs the centre frame (into `matched_centre_`, returned) or the centred pair's frame closest
  // to it in sharpness (in place) when they differ (ChangeOptions::sharpness_match_ratio).
  const cv::Mat& MatchSharpness(const cv::Mat& centre);
  struct Mismatch {
    float noise = -1, registration = -1;  // negative: not measured
  };
  static Mismatch MeasureMismatch(const cv::Mat& image, const Other& other, const cv::Mat& cover);
  // The centre frame's noise and misregistration (Entry::noise, registration): `image` (the
  // centre, sharpness matched) against both frames of the centred pair, the smaller of the two.
  void MeasureNoise(const cv::Mat& image, Entry* centre, const Other& before, const Other& after,
                    const cv::Mat& cover);
  // The allowances: the median of the frames held or the centre's own, the larger.
  void SetAllowances(const Entry& centre);
  // Also marks `evidence_changed` from the evidence pair, when there is one.
  cv::Mat MarkChanged(const cv::Mat& image, cv::Mat* evidence_changed);
  std::vector<ChangeBlob> FindBlobs(const cv::Mat& changed);

  ChangeOptions options_;
  std::vector<size_t> baselines_;  // BaselineFrames(), shortest first
  size_t lag_ = 0;                 // LagFrames(): the centre frame's place from the newest
  size_t history_frames_ = 0;      // HistoryFrames()
  int evidence_pair_ = -1;         // the index in pairs_ of the evidence pair, or -1
  cv::Size full_size_, small_size_;
  double scale_ = 1;           // full / processing
  std::deque<Entry> history_;  // the segment's last frames, at most history_frames_
  // Buffers reused from frame to frame (the masks handed out are allocated per answer).
  // Per baseline: before and after; then, with one_sided_edges, the two frames before and the two
  // after.
  std::vector<std::array<Other, 2>> pairs_;
  std::vector<cv::Mat> covers_;  // per pair: where it is compared (both cover the centre frame)
  cv::Mat unvisited_;            // changed pixels not yet in a component
  std::vector<cv::Point> seeds_, fill_;  // the changed pixels; those waiting to be filled
  cv::Mat strength_;                     // CV_32F signed change of the changed pixels
  float noise_ = 0, allowance_ = 0;      // the allowances in force (SetAllowances)
  // MatchSharpness's buffers: the answer; a neighbour's grey times its cover and the cover
  // (CV_32F), their blurs, and where it does not cover.
  cv::Mat matched_centre_, blurred_;
  cv::Mat masked_, weight_, blurred_masked_, blurred_weight_, outside_;
};

// Durations in seconds, speeds in pixels a second (FrameRate), floors in frames in brackets; the
// defaults are the frame counts tuned at 25 frames a second.
struct BlobTrackOptions {
  double gate_px = 3;  // a blob continues a track within this of its predicted position,
  double gate_growth_px_s = 6.25;  // growing by this for each second unseen after the first frame
  // ... and by this fraction of the track's own displacement since its last blob: between frames
  // a second apart a car turning at a junction leaves its straight-line prediction by a good part
  // of the 50-80 px it moved (the low-frame-rate mode sets it; at video rates a frame's
  // displacement is a pixel or two and it would change nothing).
  double gate_speed_fraction = 0;
  double max_gap_s = 0.4;         // time a track may go without a blob [2 frames]
  double min_duration_s = 1;      // blobs seen this long before a track can be confirmed [3]
  double min_hit_fraction = 0.6;  // of the frames since the track began
  double min_travel_px = 4;       // ground-relative displacement of the straight-line fit
  // Positions about that line, at most (steady motion). A car's blob (the ground it uncovers as
  // well as the car) changes shape as it goes, and a car turning at a junction or a walker
  // turning a corner leaves the line over the track's life: at 1.2 px, pieces of such tracks
  // were refused while a blob lay on the object in every frame (docs/front-end.md).
  double max_fit_rms_px = 3;
  // ... and in noisy video (AddFrame's noise_scale above 1) that divided by the noise scale, as the
  // travel is multiplied by it, down to this: heavily compressed video's drifting road markings
  // pass a looser line (docs/front-end.md).
  double noisy_fit_rms_px = 1.2;
  // In noisy video (AddFrame's noise_scale above `noisy_area_scale`) blobs larger than this are
  // not followed (0: any size): in heavily compressed video (CRF 38, a noise scale of 4-6) the
  // misregistered edges of the ground make blobs of a car's size that drift with the ground's
  // error. A car without texture is followed in cleaner video only. Clean video measures 1,
  // the simulated thermal look at most 1.3 in nine frames of ten.
  int noisy_max_area_px = 80;
  double noisy_area_scale = 2;
  // A plausible top speed on the ground: 50 m/s at 0.2 m a pixel (50 px/s, a walker's or a slow
  // car's, until session 29: cars were left to the feature tracks).
  double max_speed_px_s = 250;
  // A track seen once has no velocity yet: its next blob may lie up to this far a second from it
  // (a plausible top speed; 0: the gate of the others). The low-frame-rate mode sets it, where a
  // car moves tens of pixels between frames.
  double new_track_speed_px_s = 0;
  // A plausible top speed on the ground, metres a second (180 km/h): where the metadata gives the
  // ground's scale (AddFrame's `scale`), the two speeds above in pixels a second are this at the
  // local scale of the track instead (the new tracks' gate only when new_track_speed_px_s is
  // set). 0: the pixel speeds always. At 1.2 m a pixel it is 42 px/s, where 250 px/s spanned a
  // 1 fps frame 360 pixels wide (issue 24, item 1; docs/front-end.md, "Ground scale").
  double max_speed_m_s = 50;
  double box_margin_px = 2;
  Status Validate() const;
};

// Follows change blobs over time in ground-compensated coordinates; see the file comment.
// Confirmed tracks come out as target tracks without supporting features.
class BlobTracker {
 public:
  BlobTracker(const BlobTrackOptions& options, FrameRate rate);

  // The blobs of frame `frame` and the ground motion since the previous frame (full resolution).
  // `noise_scale` (at least 1) multiplies the travel a track needs to be confirmed and divides the
  // line allowance (to no less than noisy_fit_rms_px): the change detector's misregistration
  // allowance over ChangeOptions::clean_registration_px, so that in heavily compressed video,
  // where the ground's own differences wander, a blob track must travel further than they, and more
  // steadily. `scale`, when the metadata gives one for the frame: the ground's scale in it (full
  // resolution pixels), for the speed limits (BlobTrackOptions::max_speed_m_s).
  void AddFrame(int64_t frame, const std::vector<ChangeBlob>& blobs,
                const Eigen::Matrix3d& current_from_previous, double noise_scale = 1,
                const GroundScale* scale = nullptr);
  // Confirmed tracks that ended since the last call.
  std::vector<TargetTrack> TakeFinished();
  // Ends every track (end of the video or a chain break).
  void FinishAll();

  // The tracks followed, so that a resumed run goes on exactly from the latest frame
  // (docs/reliability.md, "Resume"). RestoreState is false when `in` is malformed.
  void SaveState(ByteWriter* out) const;
  bool RestoreState(ByteReader* in);

 private:
  // The least-squares line p(t) = a + v t through a track's hits, in the coordinates of its first
  // frame (t counted from that frame), kept as running sums: constant work per hit.
  struct LineFit {
    double n = 0, st = 0, stt = 0, spp = 0;
    Eigen::Vector2d sp{0, 0}, stp{0, 0};
    void Add(double t, const Eigen::Vector2d& p);
    Eigen::Vector2d Velocity() const;
    double Rms() const;  // of the hits about the line
  };
  struct Track {
    TargetTrack target;
    Eigen::Matrix3d current_from_anchor = Eigen::Matrix3d::Identity();  // anchor: first frame
    Eigen::Vector2d last_anchored{0, 0};  // the latest hit, anchor coordinates
    LineFit fit;
    Eigen::Vector2d velocity{0, 0};  // anchor pixels per frame, from the fit
    int64_t first_frame = 0;
    int hits = 0;
    bool confirmed = false;
  };
  // AddFrame with the blobs it follows.
  void Follow(int64_t frame, const std::vector<ChangeBlob>& blobs,
              const Eigen::Matrix3d& current_from_previous, double noise_scale,
              const GroundScale* scale);
  void End(Track* track);

  BlobTrackOptions options_;
  // The options at the video's frame rate.
  double gate_growth_px_ = 0;  // per frame unseen
  int max_gap_frames_ = 0;
  int min_frames_ = 0;
  double max_speed_px_ = 0;        // per frame
  double new_track_speed_px_ = 0;  // per frame
  double max_speed_m_ = 0;         // per frame
  std::vector<Track> active_;
  std::vector<TargetTrack> finished_;
  int64_t next_id_ = 1;
};

// Keeps a target track only when the change detector saw a change under enough of its
// observations (TargetObservation::change), among those where it could look.
bool SupportedByChange(const TargetTrack& track, double min_fraction);

// A moving car changes the image where it was as well as where it is, and between two cars that
// follow each other the differences merge: the change detector can follow such a blob as if it
// were an object of its own, at the car's speed and a few metres from it. A track found by change
// detection alone (no observation with features) is such an echo when, on at least
// `min_fraction` of its frames, a feature-tracked target that moves at `min_mover_speed_px_s` or
// more (mean, pixels a second) is within `distance_px` of it with a velocity within
// `velocity_px_s` of its own. Slow feature tracks are not taken as movers: walkers side by side
// are each other's neighbours, not echoes.
struct ChangeEchoOptions {
  bool enabled = true;
  double distance_px = 40;
  // DropCarPieces: a piece of a car lies within this distance of the car's longer track, on at
  // least this fraction of its frames.
  double piece_distance_px = 16;
  double piece_min_fraction = 0.6;
  double velocity_px_s = 12.5;
  double min_mover_speed_px_s = 25;
  double min_fraction = 0.8;
  Status Validate() const;
};

// `tracks` less the change-only tracks that echo movers (see ChangeEchoOptions): ones followed by
// their features, or longer change-only tracks (cars without texture, followed by their change),
// in their order. Observations must be in increasing frame order, as TargetTrack keeps them.
std::vector<TargetTrack> DropChangeEchoes(std::vector<TargetTrack> tracks,
                                          const ChangeEchoOptions& options, FrameRate rate);

// `tracks` less the pieces of cars that longer tracks follow: a track (of features or of change)
// within `piece_distance_px` of a longer mover on at least `piece_min_fraction` of its frames,
// whatever their velocities (the corners at one end of a dark car, beside the track of its whole
// change blob, which the target tracker carried on to the next car along the road; their
// velocities agree only on average). Called
// after the pieces are joined (LinkFragments): before, dropping pieces changed what was joined,
// and cost precision on the tuning seeds of `hard-traffic` (docs/front-end.md).
std::vector<TargetTrack> DropCarPieces(std::vector<TargetTrack> tracks,
                                       const ChangeEchoOptions& options, FrameRate rate);

}  // namespace saker::track
