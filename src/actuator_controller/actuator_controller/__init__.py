"""Joint controllers (PP-NFTSMC-ESO and baselines): ROS-free laws and the controller node."""
