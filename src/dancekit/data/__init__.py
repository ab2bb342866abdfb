"""dancekit.data"""
