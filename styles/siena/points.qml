<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>
<qgis version="3.22.0-Białowieża" styleCategories="Symbology|Labeling" labelsEnabled="1">
  <renderer-v2 type="categorizedSymbol" attr="code" symbollevels="0" enableorderby="0" forceraster="0" referencescale="-1">
    <categories>
      <category value="ALB01001" symbol="0" render="true" label="ALBERO albero isolato" />
      <category value="QUO01001" symbol="1" render="true" label="PUNTO_QUOTATO punto quotato" />
      <category value="TOP01001" symbol="2" render="true" label="TOPONIMO toponimo (località)" />
    </categories>
    <symbols>
      <symbol type="marker" name="0" alpha="1" clip_to_extent="1" force_rhr="0">
        <layer class="SimpleMarker" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="name" value="circle" type="QString" />
            <Option name="size" value="1.33333" type="QString" />
            <Option name="size_unit" value="MM" type="QString" />
            <Option name="color" value="0,0,0,0" type="QString" />
            <Option name="outline_color" value="51,204,0,255" type="QString" />
            <Option name="outline_style" value="solid" type="QString" />
            <Option name="outline_width" value="0.13" type="QString" />
            <Option name="outline_width_unit" value="MM" type="QString" />
            <Option name="offset" value="0,-0.333333" type="QString" />
            <Option name="offset_unit" value="MM" type="QString" />
            <Option name="angle" value="0" type="QString" />
          </Option>
          <prop k="name" v="circle" />
          <prop k="size" v="1.33333" />
          <prop k="size_unit" v="MM" />
          <prop k="color" v="0,0,0,0" />
          <prop k="outline_color" v="51,204,0,255" />
          <prop k="outline_style" v="solid" />
          <prop k="outline_width" v="0.13" />
          <prop k="outline_width_unit" v="MM" />
          <prop k="offset" v="0,-0.333333" />
          <prop k="offset_unit" v="MM" />
          <prop k="angle" v="0" />
        </layer>
        <layer class="SimpleMarker" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="name" value="line" type="QString" />
            <Option name="size" value="0.666667" type="QString" />
            <Option name="size_unit" value="MM" type="QString" />
            <Option name="color" value="0,0,0,0" type="QString" />
            <Option name="outline_color" value="51,204,0,255" type="QString" />
            <Option name="outline_style" value="solid" type="QString" />
            <Option name="outline_width" value="0.13" type="QString" />
            <Option name="outline_width_unit" value="MM" type="QString" />
            <Option name="offset" value="0,0.666667" type="QString" />
            <Option name="offset_unit" value="MM" type="QString" />
            <Option name="angle" value="0" type="QString" />
          </Option>
          <prop k="name" v="line" />
          <prop k="size" v="0.666667" />
          <prop k="size_unit" v="MM" />
          <prop k="color" v="0,0,0,0" />
          <prop k="outline_color" v="51,204,0,255" />
          <prop k="outline_style" v="solid" />
          <prop k="outline_width" v="0.13" />
          <prop k="outline_width_unit" v="MM" />
          <prop k="offset" v="0,0.666667" />
          <prop k="offset_unit" v="MM" />
          <prop k="angle" v="0" />
        </layer>
      </symbol>
      <symbol type="marker" name="1" alpha="1" clip_to_extent="1" force_rhr="0">
        <layer class="SimpleMarker" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="name" value="circle" type="QString" />
            <Option name="size" value="0.7" type="QString" />
            <Option name="size_unit" value="MM" type="QString" />
            <Option name="color" value="0,0,255,255" type="QString" />
            <Option name="outline_color" value="0,0,255,255" type="QString" />
            <Option name="outline_style" value="no" type="QString" />
            <Option name="outline_width" value="0.13" type="QString" />
            <Option name="outline_width_unit" value="MM" type="QString" />
            <Option name="offset" value="0,0" type="QString" />
            <Option name="offset_unit" value="MM" type="QString" />
            <Option name="angle" value="0" type="QString" />
          </Option>
          <prop k="name" v="circle" />
          <prop k="size" v="0.7" />
          <prop k="size_unit" v="MM" />
          <prop k="color" v="0,0,255,255" />
          <prop k="outline_color" v="0,0,255,255" />
          <prop k="outline_style" v="no" />
          <prop k="outline_width" v="0.13" />
          <prop k="outline_width_unit" v="MM" />
          <prop k="offset" v="0,0" />
          <prop k="offset_unit" v="MM" />
          <prop k="angle" v="0" />
        </layer>
      </symbol>
      <symbol type="marker" name="2" alpha="1" clip_to_extent="1" force_rhr="0">
        <layer class="SimpleMarker" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="name" value="circle" type="QString" />
            <Option name="size" value="0.6" type="QString" />
            <Option name="size_unit" value="MM" type="QString" />
            <Option name="color" value="0,0,0,255" type="QString" />
            <Option name="outline_color" value="0,0,0,255" type="QString" />
            <Option name="outline_style" value="no" type="QString" />
            <Option name="outline_width" value="0.6" type="QString" />
            <Option name="outline_width_unit" value="MM" type="QString" />
            <Option name="offset" value="0,0" type="QString" />
            <Option name="offset_unit" value="MM" type="QString" />
            <Option name="angle" value="0" type="QString" />
          </Option>
          <prop k="name" v="circle" />
          <prop k="size" v="0.6" />
          <prop k="size_unit" v="MM" />
          <prop k="color" v="0,0,0,255" />
          <prop k="outline_color" v="0,0,0,255" />
          <prop k="outline_style" v="no" />
          <prop k="outline_width" v="0.6" />
          <prop k="outline_width_unit" v="MM" />
          <prop k="offset" v="0,0" />
          <prop k="offset_unit" v="MM" />
          <prop k="angle" v="0" />
        </layer>
      </symbol>
    </symbols>
    <source-symbol>
      <symbol type="marker" name="0" alpha="1" clip_to_extent="1" force_rhr="0">
        <layer class="SimpleMarker" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="name" value="circle" type="QString" />
            <Option name="size" value="1.33333" type="QString" />
            <Option name="size_unit" value="MM" type="QString" />
            <Option name="color" value="0,0,0,0" type="QString" />
            <Option name="outline_color" value="51,204,0,255" type="QString" />
            <Option name="outline_style" value="solid" type="QString" />
            <Option name="outline_width" value="0.13" type="QString" />
            <Option name="outline_width_unit" value="MM" type="QString" />
            <Option name="offset" value="0,-0.333333" type="QString" />
            <Option name="offset_unit" value="MM" type="QString" />
            <Option name="angle" value="0" type="QString" />
          </Option>
          <prop k="name" v="circle" />
          <prop k="size" v="1.33333" />
          <prop k="size_unit" v="MM" />
          <prop k="color" v="0,0,0,0" />
          <prop k="outline_color" v="51,204,0,255" />
          <prop k="outline_style" v="solid" />
          <prop k="outline_width" v="0.13" />
          <prop k="outline_width_unit" v="MM" />
          <prop k="offset" v="0,-0.333333" />
          <prop k="offset_unit" v="MM" />
          <prop k="angle" v="0" />
        </layer>
        <layer class="SimpleMarker" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="name" value="line" type="QString" />
            <Option name="size" value="0.666667" type="QString" />
            <Option name="size_unit" value="MM" type="QString" />
            <Option name="color" value="0,0,0,0" type="QString" />
            <Option name="outline_color" value="51,204,0,255" type="QString" />
            <Option name="outline_style" value="solid" type="QString" />
            <Option name="outline_width" value="0.13" type="QString" />
            <Option name="outline_width_unit" value="MM" type="QString" />
            <Option name="offset" value="0,0.666667" type="QString" />
            <Option name="offset_unit" value="MM" type="QString" />
            <Option name="angle" value="0" type="QString" />
          </Option>
          <prop k="name" v="line" />
          <prop k="size" v="0.666667" />
          <prop k="size_unit" v="MM" />
          <prop k="color" v="0,0,0,0" />
          <prop k="outline_color" v="51,204,0,255" />
          <prop k="outline_style" v="solid" />
          <prop k="outline_width" v="0.13" />
          <prop k="outline_width_unit" v="MM" />
          <prop k="offset" v="0,0.666667" />
          <prop k="offset_unit" v="MM" />
          <prop k="angle" v="0" />
        </layer>
      </symbol>
    </source-symbol>
  </renderer-v2>
  <labeling type="simple">
    <settings calloutType="simple">
      <text-style fieldName="CASE WHEN &quot;code&quot; IN ('QUO01001') THEN format_number(z($geometry), 1) ELSE &quot;description&quot; END" isExpression="1" fontFamily="Sans Serif" fontSize="8" fontSizeUnit="Point" textColor="0,0,0,255" textOpacity="1" namedStyle="Regular" multilineHeight="1" />
      <text-buffer bufferDraw="1" bufferSize="0.8" bufferSizeUnits="MM" bufferColor="255,255,255,255" bufferOpacity="1" />
      <placement placement="6" dist="1" distUnits="MM" centroidInside="1" />
      <rendering scaleVisibility="0" obstacle="1" displayAll="0" fontLimitPixelSize="0" />
    </settings>
  </labeling>
  <layerGeometryType>0</layerGeometryType>
</qgis>
