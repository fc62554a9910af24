"""The message layer: core values <-> ROS messages, and nothing else.

``conversions`` (satellite states, visibility, observations: message objects and CDR bytes), ``cdr`` (the numpy
CDR codec they travel through), ``solution`` (the receiver's NavSatFix, velocity and status), ``rtk`` (rtkrcv's
fix, velocity, heading and status), ``diagnostics`` (diagnostic_msgs of the nodes), ``images``
(sensor_msgs/Image), ``tf`` (the trajectory player's transforms), ``streams`` (NMEA and RTCM3 as std_msgs),
``samples`` (filled samples of every gnss_sim_msgs type). Nodes build no message themselves: they call these.
"""
