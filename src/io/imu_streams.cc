#include "imu_streams.h"

#include <algorithm>
#include <iomanip>
#include <limits>
#include <sstream>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "text_parse.h"

namespace ltlo::io::detail {
namespace {

std::string secondsText(double value_s) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(3) << value_s;
  return os.str();
}

int lowerLine(int current, int line) { return current == 0 ? line : std::min(current, line); }

Vec3 gyroOf(const StampedReading& row) { return Vec3(row.values[0], row.values[1], row.values[2]); }

// Value of a 3-vector stream at t_s (inside its coverage) by linear interpolation; `cursor` moves
// forward only, so a sweep over increasing times is linear overall.
Vec3 interpolateStream(const ReadingStream& rows, double t_s, size_t* cursor) {
  while (*cursor + 1 < rows.size() && rows[*cursor + 1].t_s < t_s) ++*cursor;
  const StampedReading& a = rows[*cursor];
  const Vec3 va(a.values[0], a.values[1], a.values[2]);
  if (*cursor + 1 >= rows.size() || t_s <= a.t_s) return va;
  const StampedReading& b = rows[*cursor + 1];
  const Vec3 vb(b.values[0], b.values[1], b.values[2]);
  const double alpha = (t_s - a.t_s) / (b.t_s - a.t_s);
  return (1.0 - alpha) * va + alpha * vb;
}

}  // namespace

OrderCounts& OrderCounts::operator+=(const OrderCounts& other) {
  exact_duplicates += other.exact_duplicates;
  conflicting_duplicates += other.conflicting_duplicates;
  out_of_order += other.out_of_order;
  if (other.first_duplicate_line != 0) {
    first_duplicate_line = lowerLine(first_duplicate_line, other.first_duplicate_line);
  }
  if (other.first_out_of_order_line != 0) {
    first_out_of_order_line = lowerLine(first_out_of_order_line, other.first_out_of_order_line);
  }
  return *this;
}

OrderCounts putInTimeOrder(ReadingStream* stream, const std::string& path, double max_reorder_s) {
  ReadingStream& rows = *stream;
  OrderCounts counts;
  // File order: how far back each row goes behind the latest stamp above it.
  bool any_late = false;
  bool any_repeated = false;
  double latest_s = -std::numeric_limits<double>::infinity();
  int latest_line = 0;
  for (StampedReading& row : rows) {
    row.late = row.t_s < latest_s;
    if (row.late) {
      const double back_s = latest_s - row.t_s;
      if (back_s > max_reorder_s) {
        std::ostringstream limit;
        limit << max_reorder_s;
        throw InputError(path, row.line,
                         "timestamp " + formatTime(row.t_s) + " goes back by " +
                             formatTime(back_s) + " s behind " + formatTime(latest_s) + " (line " +
                             std::to_string(latest_line) +
                             "), more than Sequence.MaxImuReorder = " + limit.str() +
                             " s (a clock reset, or two files joined?)");
      }
      any_late = true;
    } else if (row.t_s == latest_s) {
      any_repeated = true;
    } else {
      latest_s = row.t_s;
      latest_line = row.line;
    }
  }
  if (!any_late && !any_repeated) return counts;  // the common case: nothing to do

  // Stable: rows of one stamp stay in file order, so the first of them is the one kept.
  if (any_late) {
    std::stable_sort(
        rows.begin(), rows.end(),
        [](const StampedReading& a, const StampedReading& b) { return a.t_s < b.t_s; });
  }
  size_t kept = 0;
  for (size_t i = 0; i < rows.size(); ++i) {
    const StampedReading& row = rows[i];
    if (kept > 0 && row.t_s == rows[kept - 1].t_s) {
      if (row.values == rows[kept - 1].values) {
        ++counts.exact_duplicates;
      } else {
        ++counts.conflicting_duplicates;
      }
      counts.first_duplicate_line = lowerLine(counts.first_duplicate_line, row.line);
      continue;
    }
    if (row.late) {
      ++counts.out_of_order;
      counts.first_out_of_order_line = lowerLine(counts.first_out_of_order_line, row.line);
    }
    if (kept != i) rows[kept] = row;
    ++kept;
  }
  rows.resize(kept);
  return counts;
}

std::string orderWarning(const std::string& path, const OrderCounts& counts,
                         const std::string& detail) {
  std::ostringstream os;
  os << path << ": " << counts.duplicates() << " duplicated stamps dropped";
  if (counts.duplicates() > 0) {
    os << " (";
    if (counts.conflicting_duplicates > 0) {
      os << counts.conflicting_duplicates << " with values other than the first's; ";
    }
    os << "first at line " << counts.first_duplicate_line << ")";
  }
  os << ", " << counts.out_of_order << " samples out of order sorted";
  if (counts.out_of_order > 0) os << " (first at line " << counts.first_out_of_order_line << ")";
  if (!detail.empty()) os << " [" << detail << "]";
  return os.str();
}

void checkImuGaps(const ReadingStream& stream, const std::string& path, const std::string& sensor,
                  const SequenceOptions& options) {
  for (size_t i = 1; i < stream.size(); ++i) {
    const double gap_s = stream[i].t_s - stream[i - 1].t_s;
    if (gap_s <= options.max_imu_gap_s) continue;
    const std::string message = sensor + "gap of " + secondsText(gap_s) +
                                " s before t = " + formatTime(stream[i].t_s) + " s (limit " +
                                secondsText(options.max_imu_gap_s) + " s)";
    if (options.imu_gap_policy == ImuGapPolicy::kFail) {
      throw InputError(path, stream[i].line, message);
    }
    log::warn(path, ":", stream[i].line, ": ", message, ", integrating across it");
  }
}

ImuSamples toImuSamples(const ReadingStream& stream) {
  ImuSamples samples;
  samples.reserve(stream.size());
  for (const StampedReading& row : stream) {
    const std::array<double, 6>& v = row.values;
    samples.push_back({row.t_s, Vec3(v[0], v[1], v[2]), Vec3(v[3], v[4], v[5])});
  }
  return samples;
}

ImuSamples mergeImuStreams(const ReadingStream& gyro, const std::string& gyro_path,
                           const ReadingStream& accel, const std::string& accel_path,
                           MergeTimes times, MergeSummary* summary) {
  if (accel.empty()) throw InputError(accel_path, 0, "no accelerometer samples");
  if (gyro.empty()) throw InputError(gyro_path, 0, "no gyroscope samples");
  const double t_begin_s = std::max(accel.front().t_s, gyro.front().t_s);
  const double t_end_s = std::min(accel.back().t_s, gyro.back().t_s);
  if (t_begin_s > t_end_s) {
    throw InputError(gyro_path, 0,
                     "gyroscope times [" + formatTime(gyro.front().t_s) + ", " +
                         formatTime(gyro.back().t_s) + "] do not overlap the accelerometer's [" +
                         formatTime(accel.front().t_s) + ", " + formatTime(accel.back().t_s) +
                         "] in " + accel_path);
  }
  summary->begin_s = t_begin_s;
  summary->end_s = t_end_s;
  summary->num_dropped = 0;

  ImuSamples samples;
  size_t accel_cursor = 0;
  if (times == MergeTimes::kGyro) {
    samples.reserve(gyro.size());
    for (const StampedReading& row : gyro) {
      if (row.t_s < t_begin_s || row.t_s > t_end_s) {
        ++summary->num_dropped;
        continue;
      }
      samples.push_back({row.t_s, gyroOf(row), interpolateStream(accel, row.t_s, &accel_cursor)});
    }
    if (samples.empty()) {
      throw InputError(gyro_path, 0,
                       "none of the " + std::to_string(gyro.size()) +
                           " gyroscope stamps lies inside the accelerometer's span [" +
                           formatTime(t_begin_s) + ", " + formatTime(t_end_s) + "]");
    }
    return samples;
  }

  std::vector<double> times_s;
  times_s.reserve(accel.size() + gyro.size());
  for (const StampedReading& row : accel) times_s.push_back(row.t_s);
  for (const StampedReading& row : gyro) times_s.push_back(row.t_s);
  std::sort(times_s.begin(), times_s.end());
  times_s.erase(std::unique(times_s.begin(), times_s.end()), times_s.end());
  samples.reserve(times_s.size());
  size_t gyro_cursor = 0;
  for (const double t_s : times_s) {
    if (t_s < t_begin_s || t_s > t_end_s) {
      ++summary->num_dropped;
      continue;
    }
    ImuSample sample;
    sample.t_s = t_s;
    sample.gyro_rad_s = interpolateStream(gyro, t_s, &gyro_cursor);
    sample.acc_m_s2 = interpolateStream(accel, t_s, &accel_cursor);
    samples.push_back(sample);
  }
  return samples;
}

}  // namespace ltlo::io::detail
