"""rosbag2 bags without ROS: record, play, inspect and read Jazzy-format bag directories.

A bag is a directory with metadata.yaml (version 9) and an MCAP file (profile ros2, ros2msg
schemas, cdr messages stored verbatim), readable by `ros2 bag` (Jazzy) and by rosbags.

    from vizzy_runtime.bag import BagReader, BagWriter, Player, Recorder, bag_info, BagError

    Recorder('out_bag', topics=['/camera/image']).run()      # until Ctrl-C
    Player('out_bag', rate=2.0, wait_for_subscribers=5).run()
    print(bag_info('out_bag', check=True))   # check=True: decode every chunk, check its CRC
    for topic, typename, data, log_ns, pub_ns in BagReader('out_bag').messages():
        ...

Every problem with a bag raises BagError, whose message names the path and the problem, except
a corrupt chunk (data that do not decompress or fail their CRC): reading skips it with a one-line
warning and goes on (BagReader.corrupt_chunks lists them); reindex_bag() drops them from the files.
Warnings (e.g. a recovered killed recording) go to the 'vizzy_runtime.bag' logger.
DDS is only loaded by Recorder.run() and Player.run().
"""

from .chunks import CorruptChunk
from .common import BagError, BagMessage, BagMetadata, FileInfo, QosProfile, TopicInfo
from .info import BagCheck, bag_check, bag_info
from .play import Player
from .reader import BagReader, Reindexed, reindex, reindex_bag
from .record import Recorder, default_bag_name
from .writer import BagWriter

__all__ = [
    'BagCheck', 'BagError', 'BagMessage', 'BagMetadata', 'BagReader', 'BagWriter',
    'CorruptChunk', 'FileInfo', 'Player', 'QosProfile', 'Recorder', 'Reindexed', 'TopicInfo',
    'bag_check', 'bag_info', 'default_bag_name', 'reindex', 'reindex_bag',
]
