"""Writes a ROS 2 bag in sqlite3 storage (rosbag2's .db3 layout, with metadata.yaml)
from the messages write_bag.mjs serialised (--feed), through Python's own sqlite3.

    python3 make_db3.py FEED.jsonl BAG_DIR [--killed]

--killed: as a recorder killed mid-run leaves it (rosbag2 writes in WAL mode and writes
metadata.yaml last): the first half of the messages merged into the .db3, the rest
committed to its -wal only, one more transaction begun and never committed, and the
process ended without closing the database or writing metadata.yaml.
"""
import base64
import json
import os
import sqlite3
import sys


def main(feed, bag_dir, killed=False):
    os.makedirs(bag_dir, exist_ok=True)
    name = os.path.basename(os.path.normpath(bag_dir)) + "_0.db3"
    db = sqlite3.connect(os.path.join(bag_dir, name), isolation_level=None if killed else "")
    if killed:
        db.execute("PRAGMA journal_mode=WAL")
        db.execute("PRAGMA wal_autocheckpoint=0")
        db.execute("PRAGMA cache_size=-64")  # a small cache: the open transaction spills pages into the log
    db.executescript(
        """
        CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
        CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL, metadata TEXT NOT NULL);
        CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
                            serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
        CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp INTEGER NOT NULL,
                              data BLOB NOT NULL);
        CREATE INDEX timestamp_idx ON messages (timestamp ASC);
        INSERT INTO schema VALUES (3, 'humble');
        """
    )
    topics, counts, first, last = {}, {}, None, None
    with open(feed) as f:
        feed_lines = f.readlines()
    if killed:
        db.execute("BEGIN")
    for i, line in enumerate(feed_lines):
        m = json.loads(line)
        if m["topic"] not in topics:
            topics[m["topic"]] = (len(topics) + 1, m["type"])
            db.execute("INSERT INTO topics VALUES (?, ?, ?, 'cdr', '')", (len(topics), m["topic"], m["type"]))
        t = int(m["t"])
        first = t if first is None else min(first, t)
        last = t if last is None else max(last, t)
        counts[m["topic"]] = counts.get(m["topic"], 0) + 1
        db.execute("INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)",
                   (topics[m["topic"]][0], t, base64.b64decode(m["data"])))
        if killed and i % 4 == 3:  # rosbag2 commits in batches
            db.execute("COMMIT")
            if i + 1 == len(feed_lines) // 2 // 4 * 4:
                db.execute("PRAGMA wal_checkpoint(TRUNCATE)")  # the first half into the .db3
            db.execute("BEGIN")
    if killed:
        db.execute("COMMIT")
        db.execute("BEGIN")
        for _ in range(64):  # a batch begun and never committed: its pages are in the log, uncommitted
            db.execute("INSERT INTO messages (topic_id, timestamp, data) VALUES (1, 0, ?)", (os.urandom(4096),))
        os._exit(0)
    db.commit()
    db.close()
    with open(os.path.join(bag_dir, "metadata.yaml"), "w") as y:
        y.write("rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n")
        y.write(f"  relative_file_paths:\n    - {name}\n")
        y.write(f"  duration:\n    nanoseconds: {last - first}\n  starting_time:\n    nanoseconds_since_epoch: {first}\n")
        y.write(f"  message_count: {sum(counts.values())}\n  topics_with_message_count:\n")
        for topic, (_, type_name) in topics.items():
            y.write(f"    - topic_metadata:\n        name: {topic}\n        type: {type_name}\n"
                    f"        serialization_format: cdr\n        offered_qos_profiles: \"\"\n"
                    f"      message_count: {counts[topic]}\n")
        y.write("  compression_format: \"\"\n  compression_mode: \"\"\n")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], "--killed" in sys.argv[3:])
