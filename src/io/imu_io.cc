#include "ltlo/io/imu_io.h"

#include <algorithm>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "parsers.h"
#include "text_parse.h"

namespace ltlo::io {
namespace {

// One parsed line of a timestamped file: time and the values after it.
struct StampedRow {
  double t_s = 0.0;
  std::vector<double> values;
};

enum class TimeUnit { kSeconds, kNanoseconds };

std::string secondsText(double value_s) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(3) << value_s;
  return os.str();
}

// Reads "t v1 .. vn" lines (separator and/or whitespace), checking finiteness, strictly
// increasing time and gaps against the options (the gap is reported at the later line).
std::vector<StampedRow> parseStampedRows(std::istream& in, const std::string& path, char separator,
                                         size_t num_values, TimeUnit unit,
                                         const SequenceOptions& options) {
  std::vector<StampedRow> rows;
  detail::LineReader lines(in);
  while (lines.next()) {
    const std::string& line = lines.line();
    const int line_number = lines.number();
    if (detail::isCommentOrBlank(line)) continue;
    // EuRoC headers start with "#", but some exports start with a plain "timestamp" header.
    if (rows.empty() && line.find("timestamp") != std::string::npos) continue;
    const std::vector<std::string> fields = detail::splitFields(line, separator);
    if (fields.size() != num_values + 1) {
      throw InputError(path, line_number,
                       "expected " + std::to_string(num_values + 1) + " values, found " +
                           std::to_string(fields.size()) + " in '" + line + "'");
    }
    StampedRow row;
    row.t_s = unit == TimeUnit::kNanoseconds
                  ? detail::parseNanosecondsAsSeconds(fields[0], path, line_number)
                  : detail::parseFinite(fields[0], "timestamp", path, line_number);
    for (size_t i = 1; i < fields.size(); ++i) {
      row.values.push_back(
          detail::parseFinite(fields[i], "value " + std::to_string(i + 1), path, line_number));
    }
    if (!rows.empty()) {
      const double previous_s = rows.back().t_s;
      if (row.t_s == previous_s) {
        throw InputError(path, line_number, "duplicated timestamp " + detail::formatTime(row.t_s));
      }
      if (row.t_s < previous_s) {
        throw InputError(path, line_number,
                         "timestamp " + detail::formatTime(row.t_s) +
                             " is not after the previous " + detail::formatTime(previous_s));
      }
      const double gap_s = row.t_s - previous_s;
      if (gap_s > options.max_imu_gap_s) {
        const std::string message = "gap of " + secondsText(gap_s) +
                                    " s before t = " + detail::formatTime(row.t_s) + " s (limit " +
                                    secondsText(options.max_imu_gap_s) + " s)";
        if (options.imu_gap_policy == ImuGapPolicy::kFail) {
          throw InputError(path, line_number, message);
        }
        log::warn(path, ":", line_number, ": ", message, ", integrating across it");
      }
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

std::vector<StampedRow> readStampedRows(const std::string& path, char separator, size_t num_values,
                                        TimeUnit unit, const SequenceOptions& options) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open IMU file");
  return parseStampedRows(in, path, separator, num_values, unit, options);
}

ImuSamples toSamples(const std::vector<StampedRow>& rows) {
  ImuSamples samples;
  samples.reserve(rows.size());
  for (const StampedRow& row : rows) {
    samples.push_back({row.t_s, Vec3(row.values[0], row.values[1], row.values[2]),
                       Vec3(row.values[3], row.values[4], row.values[5])});
  }
  return samples;
}

// Value of a 3-vector stream at t_s (inside its coverage) by linear interpolation; `cursor` moves
// forward only, so a sweep over increasing times is linear overall.
Vec3 interpolateRows(const std::vector<StampedRow>& rows, double t_s, size_t* cursor) {
  while (*cursor + 1 < rows.size() && rows[*cursor + 1].t_s < t_s) ++*cursor;
  const StampedRow& a = rows[*cursor];
  const Vec3 va(a.values[0], a.values[1], a.values[2]);
  if (*cursor + 1 >= rows.size() || t_s <= a.t_s) return va;
  const StampedRow& b = rows[*cursor + 1];
  const Vec3 vb(b.values[0], b.values[1], b.values[2]);
  const double alpha = (t_s - a.t_s) / (b.t_s - a.t_s);
  return (1.0 - alpha) * va + alpha * vb;
}

}  // namespace

namespace detail {

ImuSamples parseImuText(std::istream& in, const std::string& path, const SequenceOptions& options) {
  return toSamples(parseStampedRows(in, path, ' ', 6, TimeUnit::kSeconds, options));
}

ImuSamples parseEurocImuCsv(std::istream& in, const std::string& path,
                            const SequenceOptions& options) {
  return toSamples(parseStampedRows(in, path, ',', 6, TimeUnit::kNanoseconds, options));
}

}  // namespace detail

ImuSamples readImuText(const std::string& path, const SequenceOptions& options) {
  return toSamples(readStampedRows(path, ' ', 6, TimeUnit::kSeconds, options));
}

ImuSamples readEurocImuCsv(const std::string& path, const SequenceOptions& options) {
  return toSamples(readStampedRows(path, ',', 6, TimeUnit::kNanoseconds, options));
}

ImuSamples readOpenLorisImu(const std::string& accel_path, const std::string& gyro_path,
                            const SequenceOptions& options) {
  const std::vector<StampedRow> accel =
      readStampedRows(accel_path, ' ', 3, TimeUnit::kSeconds, options);
  const std::vector<StampedRow> gyro =
      readStampedRows(gyro_path, ' ', 3, TimeUnit::kSeconds, options);
  if (accel.empty()) throw InputError(accel_path, 0, "no accelerometer samples");
  if (gyro.empty()) throw InputError(gyro_path, 0, "no gyroscope samples");
  const double t_begin_s = std::max(accel.front().t_s, gyro.front().t_s);
  const double t_end_s = std::min(accel.back().t_s, gyro.back().t_s);
  if (t_begin_s > t_end_s) {
    throw InputError(gyro_path, 0,
                     "gyroscope times [" + detail::formatTime(gyro.front().t_s) + ", " +
                         detail::formatTime(gyro.back().t_s) +
                         "] do not overlap the accelerometer's in " + accel_path);
  }
  std::vector<double> times_s;
  times_s.reserve(accel.size() + gyro.size());
  for (const StampedRow& row : accel) times_s.push_back(row.t_s);
  for (const StampedRow& row : gyro) times_s.push_back(row.t_s);
  std::sort(times_s.begin(), times_s.end());
  times_s.erase(std::unique(times_s.begin(), times_s.end()), times_s.end());

  ImuSamples samples;
  samples.reserve(times_s.size());
  size_t accel_cursor = 0;
  size_t gyro_cursor = 0;
  for (const double t_s : times_s) {
    if (t_s < t_begin_s || t_s > t_end_s) continue;
    ImuSample sample;
    sample.t_s = t_s;
    sample.gyro_rad_s = interpolateRows(gyro, t_s, &gyro_cursor);
    sample.acc_m_s2 = interpolateRows(accel, t_s, &accel_cursor);
    samples.push_back(sample);
  }
  return samples;
}

}  // namespace ltlo::io
