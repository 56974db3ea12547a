"""The endpoint on the ROS graph: every module that imports rospy, rosgraph or genpy, and the pure rules they feed.

Through rospy: graph (RosGraph, the endpoint's node: its publishers, subscribers, services and proxies),
publisher (RawPublisher, one topic's publisher fed by the clients), reader (how its subscribers read raw messages),
service_proxy (RawServiceProxy, calls under a deadline), master (MasterLink, registrations that survive the master's
outages), peers (the facts about bridged topics' TCPROS links), network (the start-up network facts and whether the
master answers), raw_types and definitions (message and service types as raw classes, generated from their
definitions where no Python was built). Pure, without rospy or socket: registry (what the node owes the master),
peer_links (which ROS links never come up) and reachability (whether the endpoint can be reached across machines),
each beside the module that gathers its facts.

This file imports nothing, so that loading a pure rule does not load rospy: import from the modules."""
