"""dancekit.features"""
