#!/usr/bin/env python3
"""Writes a copy of a rosbag2 MCAP bag in which every body holds still: each topic's
messages carry the topic's first message with their own header stamp (the cell at rest at
its first frame, recorded for as long as the original).

    target/py/bin/python bench/hold_bag.py IN.mcap OUT.mcap

Every message here is a `chronotope_msgs/VoxelGrid` (or any message whose CDR payload starts
with a `std_msgs/Header`): the stamp is the 8 bytes after the 4-byte CDR encapsulation header.
Schemas, channels and the bag's metadata records are copied as they are.
"""

import sys

from mcap.reader import make_reader
from mcap.writer import Writer


def main(src: str, dst: str) -> None:
    with open(src, "rb") as f_in, open(dst, "wb") as f_out:
        reader = make_reader(f_in)
        summary = reader.get_summary()
        header = reader.get_header()
        writer = Writer(f_out)
        writer.start(profile=header.profile, library="chronotope bench/hold_bag.py")
        schema_ids = {}
        for sid, s in summary.schemas.items():
            schema_ids[sid] = writer.register_schema(s.name, s.encoding, s.data)
        channel_ids = {}
        for cid, c in summary.channels.items():
            channel_ids[cid] = writer.register_channel(
                c.topic, c.message_encoding, schema_ids.get(c.schema_id, 0), c.metadata
            )
        for m in reader.iter_metadata():
            writer.add_metadata(m.name, m.metadata)
        first = {}
        held = 0
        for _, channel, message in reader.iter_messages(log_time_order=True):
            data = message.data
            if channel.id not in first:
                first[channel.id] = data
            else:
                data = first[channel.id][:4] + data[4:12] + first[channel.id][12:]
                held += 1
            writer.add_message(
                channel_ids[channel.id],
                log_time=message.log_time,
                data=data,
                publish_time=message.publish_time,
                sequence=message.sequence,
            )
        writer.finish()
    print(f"{dst}: {held} messages held at their topic's first frame")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
