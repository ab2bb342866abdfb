"""dancekit.audio"""
