"""What travels between the engine and the controller: the contract both sides keep (contract), ROS 1 messages
encoded and decoded without rospy (rosmsgs), and the joint-trajectory CSV files of offline runs (joint_csv).
"""
