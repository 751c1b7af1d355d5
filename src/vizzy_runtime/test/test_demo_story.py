"""The demo's "what happened" lines, from hand-made messages."""

from vizzy_runtime.demo import _Story
from vizzy_runtime.ros import message

GazeState = message('active_vision_msgs/msg/GazeState')
GazeCommand = message('active_vision_msgs/msg/GazeCommand')
CylinderArray = message('active_vision_msgs/msg/CylinderArray')
Cylinder = message('active_vision_msgs/msg/Cylinder')
FoveatedDetectionArray = message('active_vision_msgs/msg/FoveatedDetectionArray')
FoveatedDetection = message('active_vision_msgs/msg/FoveatedDetection')
MapObjectArray = message('active_vision_msgs/msg/MapObjectArray')
MapObject = message('active_vision_msgs/msg/MapObject')


def test_story_counts_gaze_holders_saccades_and_findings() -> None:
    story = _Story()
    for source, in_saccade in [('', False), ('foveation', True), ('foveation', True),
                               ('foveation', False), ('stereo_ses', True)]:
        story.add('/gaze/state', GazeState(active_source=source, in_saccade=in_saccade))
    story.add('/gaze/command', GazeCommand(source='stereo_ses'))
    story.add('/gaze/command', GazeCommand(source='stereo_ses'))
    story.add('/cylinders', CylinderArray(cylinders=[Cylinder(), Cylinder()]))
    story.add('/cylinders', CylinderArray(cylinders=[]))
    story.add('/foveation/detections', FoveatedDetectionArray(detections=[
        FoveatedDetection(label='can', score=0.9, pass_index=0),
        FoveatedDetection(label='jar', score=0.4, pass_index=1),
        FoveatedDetection(label='box', score=0.6, pass_index=1)]))
    lines = story.lines()
    assert lines[0] == ('gaze held by: foveation 60%, idle 20%, stereo_ses 20% of the time; '
                        '2 saccades')
    assert 'gaze commands: stereo_ses 2' in lines
    assert '/cylinders: at most 2 in one message' in lines
    assert lines[-1] == 'foveation best label per recognition: box x1'


def test_story_tells_the_last_object_map() -> None:
    story = _Story()
    story.add('/objects/map', MapObjectArray(objects=[MapObject(label='can', confirmed=True)]))
    story.add('/objects/map', MapObjectArray(objects=[
        MapObject(label='can', confirmed=True, established=True),
        MapObject(label='jar', confirmed=True, established=True),
        MapObject(label='can', confirmed=True, established=True),
        MapObject(label='', established=True),
        MapObject(label='box')]))
    assert story.lines() == ['object map at the end: 3 confirmed (can x2, jar x1), '
                             '1 established unconfirmed, 1 tentative (scored against the ground '
                             'truth on summary.png)']


def test_story_without_a_map_says_nothing_of_it() -> None:
    story = _Story()
    story.add('/gaze/state', GazeState(active_source='', in_saccade=False))
    assert not any('object map' in line for line in story.lines())
