#!/usr/bin/env python3
"""Writes a rosbag2 SQLite folder (metadata.yaml + db3_0.db3, rosbag2's own schema) holding the
messages make_ros2_recordings.js serialized with @foxglove/rosmsg2-serialization (messages.json):
the same CDR bytes as its MCAP files, stored the way rosbag2's sqlite3 plugin stores them.

usage: make_db3.py MESSAGES_JSON OUT_DIR
"""
import base64
import json
import os
import sqlite3
import sys


def main():
    messages_json, out = sys.argv[1], sys.argv[2]
    with open(messages_json) as f:
        messages = json.load(f)
    os.makedirs(out, exist_ok=True)
    db_path = os.path.join(out, "db3_0.db3")
    if os.path.exists(db_path):
        os.remove(db_path)
    db = sqlite3.connect(db_path)
    # rosbag2_storage_default_plugins' schema (sqlite_storage.cpp, Foxy to Humble).
    db.execute("CREATE TABLE schema(schema_version INTEGER PRIMARY KEY,ros_distro TEXT NOT NULL)")
    db.execute("INSERT INTO schema VALUES (3, 'humble')")
    db.execute("CREATE TABLE metadata(id INTEGER PRIMARY KEY,metadata_version INTEGER NOT NULL,metadata TEXT NOT NULL)")
    db.execute("CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,"
               "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL)")
    db.execute("CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,timestamp INTEGER NOT NULL,"
               "data BLOB NOT NULL)")
    db.execute("CREATE INDEX timestamp_idx ON messages (timestamp ASC)")
    ids = {}
    counts = {}
    for m in messages:
        if m["topic"] not in ids:
            ids[m["topic"]] = len(ids) + 1
            db.execute("INSERT INTO topics VALUES (?, ?, ?, 'cdr', '')", (ids[m["topic"]], m["topic"], m["type"]))
        counts[m["topic"]] = counts.get(m["topic"], 0) + 1
        db.execute("INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)",
                   (ids[m["topic"]], int(m["time_ns"]), base64.b64decode(m["cdr"])))
    db.commit()
    db.close()
    types = {m["topic"]: m["type"] for m in messages}
    times = [int(m["time_ns"]) for m in messages]
    with open(os.path.join(out, "metadata.yaml"), "w") as f:
        f.write("rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n")
        f.write("  duration:\n    nanoseconds: %d\n  starting_time:\n    nanoseconds_since_epoch: %d\n"
                % (max(times) - min(times), min(times)))
        f.write("  message_count: %d\n  topics_with_message_count:\n" % len(messages))
        for topic, n in counts.items():
            f.write("    - topic_metadata:\n        name: %s\n        type: %s\n        serialization_format: cdr\n"
                    "        offered_qos_profiles: \"\"\n      message_count: %d\n" % (topic, types[topic], n))
        f.write("  compression_format: \"\"\n  compression_mode: \"\"\n  relative_file_paths:\n    - db3_0.db3\n")


if __name__ == "__main__":
    main()
