#include "hmap/ros/ros2_recording.hpp"

#include <sqlite3.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <map>
#include <set>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/ros/cdr.hpp"
#include "hmap/ros/mcap_reader.hpp"

namespace hmap::ros::access {

namespace fs = std::filesystem;

namespace {

struct StoredTopic {
  std::string name;
  std::string type;      ///< e.g. sensor_msgs/msg/PointCloud2
  std::string encoding;  ///< cdr
  std::uint64_t messages = 0;
};

/// Where one message is, in whichever file holds it.
struct StoredMessage {
  std::size_t store = 0;
  std::uint64_t time_ns = 0;
  mcap::MessageRef ref;     ///< MCAP
  std::int64_t rowid = -1;  ///< SQLite
};

/// One file of a recording.
class Store {
 public:
  virtual ~Store() = default;
  [[nodiscard]] virtual std::vector<StoredTopic> topics() const = 0;
  [[nodiscard]] virtual std::vector<StoredMessage> list(const std::string& topic) const = 0;
  [[nodiscard]] virtual std::vector<std::uint8_t> read(const StoredMessage& m) const = 0;
  std::string name;
  std::uint64_t start_ns = 0;
  std::uint64_t end_ns = 0;
  std::uint64_t messages = 0;
  std::size_t chunks = 0;
  std::set<std::string> compressions;
  std::vector<std::string> warnings;
};

class McapStore final : public Store {
 public:
  explicit McapStore(const fs::path& path) : reader_(mcap::file_source(path), path.string()) {
    name = path.string();
    const auto& info = reader_.info();
    start_ns = info.start_time;
    end_ns = info.end_time;
    messages = info.messages;
    chunks = info.chunks.size();
    for (const auto& c : info.chunks) compressions.insert(c.compression.empty() ? "none" : c.compression);
    warnings = info.warnings;
  }
  [[nodiscard]] std::vector<StoredTopic> topics() const override {
    std::map<std::string, StoredTopic> by_name;
    const auto& info = reader_.info();
    for (const auto& [id, ch] : info.channels) {
      auto& t = by_name[ch.topic];
      t.name = ch.topic;
      const auto schema = info.schemas.find(ch.schema_id);
      t.type = schema == info.schemas.end() ? std::string() : schema->second.name;
      t.encoding = ch.message_encoding;
      const auto count = info.message_counts.find(id);
      if (count != info.message_counts.end()) t.messages += count->second;
    }
    std::vector<StoredTopic> out;
    for (auto& [n, t] : by_name) out.push_back(std::move(t));
    return out;
  }
  [[nodiscard]] std::vector<StoredMessage> list(const std::string& topic) const override {
    std::set<std::uint16_t> ids;
    for (const auto& [id, ch] : reader_.info().channels) {
      if (ch.topic == topic) ids.insert(id);
    }
    std::vector<StoredMessage> out;
    for (const auto& ref : reader_.messages(ids)) out.push_back({0, ref.log_time, ref, -1});
    return out;
  }
  [[nodiscard]] std::vector<std::uint8_t> read(const StoredMessage& m) const override { return reader_.read(m.ref); }

 private:
  mcap::Reader reader_;
};

/// rosbag2's SQLite storage: tables topics(id, name, type, serialization_format) and
/// messages(id, topic_id, timestamp, data).
class SqliteStore final : public Store {
 public:
  explicit SqliteStore(const fs::path& path) {
    name = path.string();
    if (!fs::is_regular_file(path)) throw InputError(name, "", "cannot open: no such file");
    sqlite3* db = nullptr;
    const int rc = sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr);
    db_.reset(db);
    if (rc != SQLITE_OK) throw InputError(name, "", std::string("cannot open as SQLite: ") + sqlite3_errstr(rc));
    auto q = query("SELECT id, name, type, serialization_format FROM topics ORDER BY id");
    while (step(q.get())) {
      StoredTopic t;
      t.name = text(q.get(), 1);
      t.type = text(q.get(), 2);
      t.encoding = text(q.get(), 3);
      topics_[sqlite3_column_int64(q.get(), 0)] = t;
    }
    auto c = query("SELECT topic_id, COUNT(*), MIN(timestamp), MAX(timestamp) FROM messages GROUP BY topic_id");
    bool first = true;
    while (step(c.get())) {
      const auto it = topics_.find(sqlite3_column_int64(c.get(), 0));
      const auto n = static_cast<std::uint64_t>(sqlite3_column_int64(c.get(), 1));
      const auto lo = static_cast<std::uint64_t>(sqlite3_column_int64(c.get(), 2));
      const auto hi = static_cast<std::uint64_t>(sqlite3_column_int64(c.get(), 3));
      if (it == topics_.end()) throw InputError(name, "table messages", "messages of a topic id the topics table lacks");
      it->second.messages = n;
      messages += n;
      start_ns = first ? lo : std::min(start_ns, lo);
      end_ns = first ? hi : std::max(end_ns, hi);
      first = false;
    }
    compressions.insert("none");
  }
  [[nodiscard]] std::vector<StoredTopic> topics() const override {
    std::vector<StoredTopic> out;
    for (const auto& [id, t] : topics_) out.push_back(t);
    return out;
  }
  [[nodiscard]] std::vector<StoredMessage> list(const std::string& topic) const override {
    std::vector<StoredMessage> out;
    for (const auto& [id, t] : topics_) {
      if (t.name != topic) continue;
      auto q = query("SELECT id, timestamp FROM messages WHERE topic_id = ? ORDER BY timestamp, id");
      sqlite3_bind_int64(q.get(), 1, id);
      while (step(q.get())) {
        StoredMessage m;
        m.rowid = sqlite3_column_int64(q.get(), 0);
        m.time_ns = static_cast<std::uint64_t>(sqlite3_column_int64(q.get(), 1));
        out.push_back(m);
      }
    }
    return out;
  }
  [[nodiscard]] std::vector<std::uint8_t> read(const StoredMessage& m) const override {
    auto q = query("SELECT data FROM messages WHERE id = ?");
    sqlite3_bind_int64(q.get(), 1, m.rowid);
    if (!step(q.get())) throw InputError(name, "message " + std::to_string(m.rowid), "is gone from the table");
    const auto* p = static_cast<const std::uint8_t*>(sqlite3_column_blob(q.get(), 0));
    const int n = sqlite3_column_bytes(q.get(), 0);
    return p == nullptr ? std::vector<std::uint8_t>() : std::vector<std::uint8_t>(p, p + n);
  }

 private:
  struct CloseDb {
    void operator()(sqlite3* db) const { sqlite3_close(db); }
  };
  struct Finalize {
    void operator()(sqlite3_stmt* s) const { sqlite3_finalize(s); }
  };
  using Statement = std::unique_ptr<sqlite3_stmt, Finalize>;

  [[nodiscard]] Statement query(const char* sql) const {
    sqlite3_stmt* s = nullptr;
    if (sqlite3_prepare_v2(db_.get(), sql, -1, &s, nullptr) != SQLITE_OK) {
      sqlite3_finalize(s);
      throw InputError(name, "", std::string("not a rosbag2 SQLite file (") + sqlite3_errmsg(db_.get()) + ")");
    }
    return Statement(s);
  }
  bool step(sqlite3_stmt* s) const {
    const int rc = sqlite3_step(s);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throw InputError(name, "", std::string("SQLite: ") + sqlite3_errmsg(db_.get()));
  }
  static std::string text(sqlite3_stmt* s, int col) {
    const auto* p = sqlite3_column_text(s, col);
    return p == nullptr ? std::string() : std::string(reinterpret_cast<const char*>(p));
  }

  std::unique_ptr<sqlite3, CloseDb> db_;
  std::map<std::int64_t, StoredTopic> topics_;
};

/// The files of a rosbag2 folder, from its metadata.yaml.
std::vector<fs::path> rosbag2_files(const fs::path& dir, std::string& storage) {
  const fs::path meta = dir / "metadata.yaml";
  if (!fs::is_regular_file(meta)) {
    throw InputError(dir.string(), "", "is a folder without metadata.yaml: not a rosbag2 recording");
  }
  YAML::Node root;
  try {
    root = YAML::LoadFile(meta.string());
  } catch (const YAML::Exception& e) {
    throw InputError(meta.string(), "line " + std::to_string(e.mark.line + 1), "not valid YAML: " + e.msg);
  }
  const YAML::Node info = root["rosbag2_bagfile_information"];
  if (!info.IsMap()) throw InputError(meta.string(), "", "has no rosbag2_bagfile_information: not rosbag2 metadata");
  std::vector<fs::path> files;
  try {
    storage = info["storage_identifier"] ? info["storage_identifier"].as<std::string>() : std::string();
    if (info["compression_format"] && !info["compression_format"].as<std::string>().empty()) {
      throw InputError(meta.string(), "compression_format",
                       "\"" + info["compression_format"].as<std::string>() +
                           "\": compressed rosbag2 files are not read by hmap (decompress with `ros2 bag convert` first)");
    }
    if (info["relative_file_paths"]) {
      for (const auto& f : info["relative_file_paths"]) files.push_back(dir / f.as<std::string>());
    }
  } catch (const YAML::Exception& e) {
    throw InputError(meta.string(), "line " + std::to_string(e.mark.line + 1), "unexpected value: " + e.msg);
  }
  if (files.empty()) throw InputError(meta.string(), "relative_file_paths", "lists no files");
  for (const auto& f : files) {
    if (!fs::is_regular_file(f)) {
      throw InputError(meta.string(), "relative_file_paths", "lists " + f.string() + ", which does not exist");
    }
  }
  return files;
}

std::string stamp_of(std::uint64_t ns) { return format("%.6f", 1e-9 * static_cast<double>(ns)); }

class Ros2Recording final : public Recording {
 public:
  explicit Ros2Recording(const fs::path& path) : path_(path.string()) {
    if (fs::is_directory(path)) {
      std::string storage;
      for (const auto& f : rosbag2_files(path, storage)) {
        std::string ext = f.extension().string();
        if (storage == "mcap" || ext == ".mcap") {
          stores_.push_back(std::make_unique<McapStore>(f));
        } else if (storage == "sqlite3" || ext == ".db3") {
          stores_.push_back(std::make_unique<SqliteStore>(f));
        } else {
          throw InputError((path / "metadata.yaml").string(), "storage_identifier",
                           "\"" + storage + "\" is not a storage hmap reads (sqlite3, mcap)");
        }
      }
      format_ = "rosbag2 (" + std::string(dynamic_cast<McapStore*>(stores_.front().get()) ? "mcap" : "sqlite3") + ", " +
                std::to_string(stores_.size()) + (stores_.size() == 1 ? " file)" : " files)");
    } else {
      stores_.push_back(std::make_unique<McapStore>(path));
      format_ = "MCAP";
    }
    for (const auto& s : stores_) {
      for (auto& t : s->topics()) {
        auto& mine = topics_[t.name];
        if (!mine.name.empty() && mine.type != t.type) {
          throw InputError(s->name, "topic " + t.name, "has type " + t.type + " here and " + mine.type + " in another file");
        }
        mine.messages += t.messages;
        mine.name = t.name;
        mine.type = t.type;
        mine.encoding = t.encoding;
      }
    }
  }

  [[nodiscard]] Summary summary() const override {
    Summary s;
    s.format = format_;
    std::set<std::string> kinds;
    bool first = true;
    for (const auto& st : stores_) {
      if (st->messages > 0) {
        s.start_time = first ? 1e-9 * static_cast<double>(st->start_ns) : std::min(s.start_time, 1e-9 * static_cast<double>(st->start_ns));
        s.end_time = first ? 1e-9 * static_cast<double>(st->end_ns) : std::max(s.end_time, 1e-9 * static_cast<double>(st->end_ns));
        first = false;
      }
      s.messages += st->messages;
      s.chunks += st->chunks;
      kinds.insert(st->compressions.begin(), st->compressions.end());
      s.warnings.insert(s.warnings.end(), st->warnings.begin(), st->warnings.end());
    }
    s.compression = kinds.empty() ? "none" : kinds.size() == 1 ? *kinds.begin() : "mixed";
    for (const auto& [name, t] : topics_) s.topics.push_back({t.name, t.type, static_cast<std::size_t>(t.messages)});
    return s;
  }

  std::vector<CloudHeader> index_clouds(const std::string& topic, std::size_t max) override {
    clouds_ = messages(topic, {cdr::kPointCloud2});
    if (max > 0 && clouds_.size() > max) clouds_.resize(max);
    std::vector<CloudHeader> out;
    for (const auto& m : clouds_) {
      const auto bytes = read(m);
      out.push_back(cdr::decode_cloud_header(bytes, stores_[m.store]->name, where(topic, m)));
    }
    return out;
  }

  [[nodiscard]] RawCloud read_cloud(std::size_t k) const override {
    const StoredMessage& m = clouds_.at(k);
    const auto bytes = read(m);
    return cdr::decode_cloud(bytes, stores_[m.store]->name, "cloud message at " + stamp_of(m.time_ns));
  }

  [[nodiscard]] std::vector<RawTransform> read_tf() const override {
    std::vector<RawTransform> out;
    for (const char* topic : {"/tf_static", "/tf"}) {
      if (topics_.count(topic) == 0) continue;
      for (const auto& m : messages(topic, {cdr::kTfMessage})) {
        cdr::decode_tf(read(m), std::strcmp(topic, "/tf_static") == 0, out, stores_[m.store]->name, where(topic, m));
      }
    }
    return out;
  }

  [[nodiscard]] std::vector<RawImu> read_imu(const std::string& topic) const override {
    std::vector<RawImu> out;
    for (const auto& m : messages(topic, {cdr::kImu})) out.push_back(cdr::decode_imu(read(m), stores_[m.store]->name, where(topic, m)));
    return out;
  }

  [[nodiscard]] std::vector<RawTransform> read_poses(const std::string& topic) const override {
    std::vector<RawTransform> out;
    const auto msgs = messages(topic, {cdr::kOdometry, cdr::kPoseStamped, cdr::kTransformStamped});
    const std::string type = topics_.at(topic).type;
    for (const auto& m : msgs) out.push_back(cdr::decode_pose(read(m), type, stores_[m.store]->name, where(topic, m)));
    return out;
  }

 private:
  [[nodiscard]] static std::string where(const std::string& topic, const StoredMessage& m) {
    return topic + " message at log time " + stamp_of(m.time_ns);
  }
  /// The messages of `topic`, refused unless it is one of `types` in CDR.
  [[nodiscard]] std::vector<StoredMessage> messages(const std::string& topic, std::initializer_list<const char*> types) const {
    const auto it = topics_.find(topic);
    if (it == topics_.end()) throw InputError(path_, "", "has no topic " + topic + " (see hmap bag-info)");
    const StoredTopic& t = it->second;
    std::string names;
    bool known = false;
    for (const char* type : types) {
      known = known || t.type == type;
      names += std::string(names.empty() ? "" : " or ") + type;
    }
    if (!known) throw InputError(path_, "topic " + topic, "has type " + t.type + ", not " + names);
    if (t.encoding != "cdr") {
      throw InputError(path_, "topic " + topic, "message encoding \"" + t.encoding + "\" is not one hmap reads (cdr)");
    }
    std::vector<StoredMessage> out;
    for (std::size_t s = 0; s < stores_.size(); ++s) {
      for (auto& m : stores_[s]->list(topic)) {
        m.store = s;
        out.push_back(m);
      }
    }
    return out;
  }
  [[nodiscard]] std::vector<std::uint8_t> read(const StoredMessage& m) const { return stores_[m.store]->read(m); }

  std::string path_;
  std::string format_;
  std::vector<std::unique_ptr<Store>> stores_;
  std::map<std::string, StoredTopic> topics_;
  std::vector<StoredMessage> clouds_;
};

}  // namespace

bool is_mcap_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  in.read(magic, 8);
  return in.gcount() == 8 && std::memcmp(magic, mcap::kMagic, 8) == 0;
}

std::unique_ptr<Recording> open_ros2(const fs::path& path) { return std::make_unique<Ros2Recording>(path); }

}  // namespace hmap::ros::access
