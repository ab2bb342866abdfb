"""dancekit.training"""
