#pragma once
// IMU readings as files deliver them (private to ltlo_io): put into time order, duplicates
// dropped, gaps checked, and separate gyroscope and accelerometer streams merged into full
// samples. Shared by the imu.txt, EuRoC and OpenLORIS readers (imu_io.cc).
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "ltlo/core/imu_sample.h"
#include "ltlo/core/sequence_options.h"

namespace ltlo::io::detail {

/// One timestamped row of an IMU file: six values for a full row (gx gy gz ax ay az), three (and
/// three zeros) for one sensor's reading.
struct StampedReading {
  double t_s = 0.0;
  std::array<double, 6> values{};
  int line = 0;          ///< 1-based line in its file, for messages
  bool has_gyro = true;  ///< imu.txt half rows: which triples the row carries
  bool has_acc = true;
  bool late = false;  ///< set by putInTimeOrder: stamped before an earlier row of the file
};
using ReadingStream = std::vector<StampedReading>;

/// What putInTimeOrder changed in one stream.
struct OrderCounts {
  size_t exact_duplicates = 0;        ///< same stamp and values as a row kept: dropped
  size_t conflicting_duplicates = 0;  ///< same stamp, other values: dropped (the first is kept)
  size_t out_of_order = 0;            ///< kept rows moved back into time order
  int first_duplicate_line = 0;       ///< lowest line of a dropped row (0: none)
  int first_out_of_order_line = 0;    ///< lowest line of a moved row (0: none)

  size_t duplicates() const { return exact_duplicates + conflicting_duplicates; }
  bool any() const { return duplicates() + out_of_order > 0; }
  OrderCounts& operator+=(const OrderCounts& other);
};

/// Sorts `stream` (file order in, strictly increasing stamps out): rows stamped before the latest
/// stamp above them by at most max_reorder_s are moved into place (stable, so rows of one stamp
/// keep their file order); of the rows sharing a stamp the first is kept. A row further back than
/// max_reorder_s throws InputError naming `path`, its line, its stamp and the size of the jump.
/// A stream already in order is left untouched (same values, same order).
OrderCounts putInTimeOrder(ReadingStream* stream, const std::string& path, double max_reorder_s);

/// The one warning line of a file whose streams putInTimeOrder changed, e.g.
/// "imu.txt: 3 duplicated stamps dropped (first at line 40), 12 samples out of order sorted
/// (first at line 9)"; `detail` (may be empty) is appended in brackets.
std::string orderWarning(const std::string& path, const OrderCounts& counts,
                         const std::string& detail);

/// Gaps between consecutive stamps of an ordered stream longer than options.max_imu_gap_s: a
/// warning each (kWarn) or InputError (kFail), at the line of the later row. `sensor` ("" or
/// "gyroscope "/"accelerometer ") starts the message.
void checkImuGaps(const ReadingStream& stream, const std::string& path, const std::string& sensor,
                  const SequenceOptions& options);

/// Full rows of an ordered stream as samples (values 0..2 gyro, 3..5 acc).
ImuSamples toImuSamples(const ReadingStream& stream);

/// Where merged samples are placed.
enum class MergeTimes {
  kGyro,   ///< at the gyroscope's stamps (imu.txt split streams)
  kUnion,  ///< at the stamps of both streams (OpenLORIS accel.txt + gyro.txt)
};

/// What mergeImuStreams kept and dropped, for its log line.
struct MergeSummary {
  double begin_s = 0.0;  ///< the interval both streams cover
  double end_s = 0.0;
  size_t num_dropped = 0;  ///< merge times outside [begin_s, end_s]
};

/// Full samples from ordered 3-value streams (values 0..2): the gyroscope and the accelerometer
/// linearly interpolated at the merge times inside the interval both cover (no extrapolation).
/// kGyro keeps each gyroscope reading as read. Throws InputError (naming the files) when a stream
/// is empty or they do not overlap.
ImuSamples mergeImuStreams(const ReadingStream& gyro, const std::string& gyro_path,
                           const ReadingStream& accel, const std::string& accel_path,
                           MergeTimes times, MergeSummary* summary);

}  // namespace ltlo::io::detail
