"""dancekit.metrics"""
