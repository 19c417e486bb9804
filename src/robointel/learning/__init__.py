"""Part II (Ch. 5-6): demonstrations, DTW, action decomposition, GMM/GMR skills, insertion and grinding; grasp/ for grasp transfer."""
