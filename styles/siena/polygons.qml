<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>
<qgis version="3.22.0-Białowieża" styleCategories="Symbology|Labeling" labelsEnabled="1">
  <renderer-v2 type="categorizedSymbol" attr="code" symbollevels="0" enableorderby="0" forceraster="0" referencescale="-1">
    <categories>
      <category value="FAB01002" symbol="0" render="true" label="FAB01002 muro perimetrale di fabbricato civile" />
      <category value="VEG01001" symbol="1" render="true" label="VEG01001 area a verde" />
    </categories>
    <symbols>
      <symbol type="fill" name="0" alpha="1" clip_to_extent="1" force_rhr="0">
        <layer class="SimpleFill" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="color" value="77,77,77,96" type="QString" />
            <Option name="style" value="solid" type="QString" />
            <Option name="outline_color" value="77,77,77,255" type="QString" />
            <Option name="outline_style" value="solid" type="QString" />
            <Option name="outline_width" value="0.3" type="QString" />
            <Option name="outline_width_unit" value="MM" type="QString" />
            <Option name="joinstyle" value="miter" type="QString" />
          </Option>
          <prop k="color" v="77,77,77,96" />
          <prop k="style" v="solid" />
          <prop k="outline_color" v="77,77,77,255" />
          <prop k="outline_style" v="solid" />
          <prop k="outline_width" v="0.3" />
          <prop k="outline_width_unit" v="MM" />
          <prop k="joinstyle" v="miter" />
        </layer>
      </symbol>
      <symbol type="fill" name="1" alpha="1" clip_to_extent="1" force_rhr="0">
        <layer class="SimpleFill" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="color" value="51,204,0,96" type="QString" />
            <Option name="style" value="solid" type="QString" />
            <Option name="outline_color" value="51,204,0,255" type="QString" />
            <Option name="outline_style" value="solid" type="QString" />
            <Option name="outline_width" value="0.3" type="QString" />
            <Option name="outline_width_unit" value="MM" type="QString" />
            <Option name="joinstyle" value="miter" type="QString" />
          </Option>
          <prop k="color" v="51,204,0,96" />
          <prop k="style" v="solid" />
          <prop k="outline_color" v="51,204,0,255" />
          <prop k="outline_style" v="solid" />
          <prop k="outline_width" v="0.3" />
          <prop k="outline_width_unit" v="MM" />
          <prop k="joinstyle" v="miter" />
        </layer>
      </symbol>
    </symbols>
    <source-symbol>
      <symbol type="fill" name="0" alpha="1" clip_to_extent="1" force_rhr="0">
        <layer class="SimpleFill" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="color" value="77,77,77,96" type="QString" />
            <Option name="style" value="solid" type="QString" />
            <Option name="outline_color" value="77,77,77,255" type="QString" />
            <Option name="outline_style" value="solid" type="QString" />
            <Option name="outline_width" value="0.3" type="QString" />
            <Option name="outline_width_unit" value="MM" type="QString" />
            <Option name="joinstyle" value="miter" type="QString" />
          </Option>
          <prop k="color" v="77,77,77,96" />
          <prop k="style" v="solid" />
          <prop k="outline_color" v="77,77,77,255" />
          <prop k="outline_style" v="solid" />
          <prop k="outline_width" v="0.3" />
          <prop k="outline_width_unit" v="MM" />
          <prop k="joinstyle" v="miter" />
        </layer>
      </symbol>
    </source-symbol>
  </renderer-v2>
  <labeling type="simple">
    <settings calloutType="simple">
      <text-style fieldName="description" isExpression="0" fontFamily="Sans Serif" fontSize="8" fontSizeUnit="Point" textColor="0,0,0,255" textOpacity="1" namedStyle="Regular" multilineHeight="1" />
      <text-buffer bufferDraw="1" bufferSize="0.8" bufferSizeUnits="MM" bufferColor="255,255,255,255" bufferOpacity="1" />
      <placement placement="1" dist="1" distUnits="MM" centroidInside="1" />
      <rendering scaleVisibility="0" obstacle="1" displayAll="0" fontLimitPixelSize="0" />
    </settings>
  </labeling>
  <layerGeometryType>2</layerGeometryType>
</qgis>
