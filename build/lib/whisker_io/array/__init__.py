"""The whisker array and how it moves: module geometry (Fig 2.15), forward
kinematics on the arm (Eq 5.1-5.2) and the whisking controllers (open loop, RCP)."""
