"""RTKLIB ``rtkrcv`` as the RTK engine (ROS-free): its configuration (``config``), the process and its
TCP streams (``process``), and its solutions read back (``solution``)."""
