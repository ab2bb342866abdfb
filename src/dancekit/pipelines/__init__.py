"""dancekit.pipelines"""
