#include "hmap/io/imu_text.hpp"

#include "hmap/io/atomic_file.hpp"

#include <charconv>

#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/io/read_support.hpp"

namespace hmap {

namespace {

/// Splits at spaces, tabs and commas (empty fields between two commas are refused by the count).
void split_fields(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == ',' || line[i] == '\r')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != ',' && line[i] != '\r') ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
}

}  // namespace

ImuSamples read_imu_text(const std::filesystem::path& path) {
  const std::string bytes = detail::read_file_bytes(path);
  const std::string source = path.string();
  ImuSamples samples;
  std::vector<std::size_t> lines_of;  // the line of each sample, for the stamp check after scaling
  detail::LineReader lines(bytes);
  std::string_view line;
  std::vector<std::string_view> tokens;
  while (lines.next(line)) {
    split_fields(line, tokens);
    if (tokens.empty() || tokens.front().front() == '#') continue;
    const std::string where = detail::line_position(lines.line_number());
    if (tokens.size() != 7 && tokens.size() != 11) {
      throw InputError(source, where, "expected 7 values (t gx gy gz ax ay az) or 11 (and qx qy qz qw), found " +
                                          std::to_string(tokens.size()));
    }
    double v[11];
    for (std::size_t k = 0; k < tokens.size(); ++k) {
      if (!detail::parse_double(tokens[k], v[k]) || !std::isfinite(v[k])) {
        throw InputError(source, where, "value " + std::to_string(k + 1) + " " + detail::quoted(tokens[k]) +
                                            " is not a finite number");
      }
    }
    ImuSample s;
    s.t = v[0];
    s.gyro = Eigen::Vector3d(v[1], v[2], v[3]);
    s.accel = Eigen::Vector3d(v[4], v[5], v[6]);
    if (tokens.size() == 11) {
      const Eigen::Quaterniond q(v[10], v[7], v[8], v[9]);
      if (!(q.norm() > 1e-6)) throw InputError(source, where, "the orientation quaternion is zero");
      s.orientation = q.normalized();
    }
    samples.push_back(s);
    lines_of.push_back(lines.line_number());
  }
  if (samples.empty()) throw InputError(source, "", "no IMU sample (lines of t gx gy gz ax ay az)");
  bool nanoseconds = true;
  for (const auto& s : samples) nanoseconds = nanoseconds && s.t > 1e14;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    if (nanoseconds) samples[k].t *= 1e-9;
    if (k > 0 && !(samples[k].t > samples[k - 1].t)) {
      throw InputError(source, detail::line_position(lines_of[k]), "stamp " + std::to_string(samples[k].t) +
                                                                       " is not after the previous line's");
    }
  }
  return samples;
}

void write_imu_text(const std::filesystem::path& path, const ImuSamples& samples) {
  std::string text = "# t [s] gx gy gz [rad/s] ax ay az [m/s^2] (specific force) [qx qy qz qw: world <- imu]\n";
  char number[32];
  const auto put = [&](double v) {
    if (!std::isfinite(v)) throw Error(path.string() + ": an IMU value is not finite");
    const auto end = std::to_chars(number, number + sizeof number, v).ptr;
    text.append(number, static_cast<std::size_t>(end - number));
  };
  for (const ImuSample& s : samples) {
    put(s.t);
    for (int i = 0; i < 3; ++i) text += ' ', put(s.gyro[i]);
    for (int i = 0; i < 3; ++i) text += ' ', put(s.accel[i]);
    if (s.orientation) {
      const Eigen::Quaterniond& q = *s.orientation;
      for (const double v : {q.x(), q.y(), q.z(), q.w()}) text += ' ', put(v);
    }
    text += '\n';
  }
  write_file_atomic(path, text);
}

}  // namespace hmap
